//! Triangle meshes, each in its own bottom-level scene, instanced into one
//! top-level scene whose instance transforms can be replaced cheaply.

use std::ptr::NonNull;

use anyhow::{bail, ensure, Context, Result};
use glam::{Affine3A, Vec3};

use super::device::Device;
use super::fpenv::call_ftz;
use super::raw;
use crate::ray::Ray;
use crate::scene::MeshGeometry;

/// The id Embree uses for "no geometry" (`RTC_INVALID_GEOMETRY_ID`, a cast
/// macro bindgen cannot translate).
pub const INVALID_ID: u32 = u32::MAX;

/// Lanes of a packet query.
pub const PACKET: usize = 16;

/// Per-lane mask of a 16-ray packet (-1 = active, 0 = inactive), with the
/// 64-byte alignment Embree requires of it.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, Default)]
pub struct Valid16(pub [i32; PACKET]);

/// One owned reference to an Embree scene.
struct SceneHandle(NonNull<raw::RTCSceneTy>);

impl SceneHandle {
    /// A new empty scene: robust (rays do not slip through shared edges).
    fn new(device: &Device, quality: raw::RTCBuildQuality) -> Result<Self> {
        // SAFETY: the device is valid for the duration of the call.
        let scene = unsafe { raw::rtcNewScene(device.as_raw()) };
        device.check(|| "create a scene".into())?;
        let scene = NonNull::new(scene).context("Embree returned no scene")?;
        // SAFETY: `scene` is a valid scene handle owned here.
        unsafe {
            raw::rtcSetSceneFlags(scene.as_ptr(), raw::RTCSceneFlags::RTC_SCENE_FLAG_ROBUST);
            raw::rtcSetSceneBuildQuality(scene.as_ptr(), quality);
        }
        device.check(|| "set scene flags and build quality".into())?;
        Ok(Self(scene))
    }

    fn commit(&self, device: &Device, what: &str) -> Result<()> {
        // SAFETY: the handle is valid; commits are only reached through
        // `&mut InstancedScene` or during construction, never concurrently
        // with queries.
        unsafe { raw::rtcCommitScene(self.0.as_ptr()) };
        device.check(|| format!("commit {what}"))
    }
}

impl Drop for SceneHandle {
    fn drop(&mut self) {
        // SAFETY: releases the one reference this handle owns.
        unsafe { raw::rtcReleaseScene(self.0.as_ptr()) }
    }
}

/// One owned reference to an Embree geometry.
struct GeometryHandle(NonNull<raw::RTCGeometryTy>);

impl GeometryHandle {
    fn new(device: &Device, kind: raw::RTCGeometryType) -> Result<Self> {
        // SAFETY: the device is valid; an unknown `kind` is reported as an
        // Embree error, checked next.
        let geometry = unsafe { raw::rtcNewGeometry(device.as_raw(), kind) };
        device.check(|| format!("create a geometry of type {}", kind.0))?;
        Ok(Self(
            NonNull::new(geometry).context("Embree returned no geometry")?,
        ))
    }
}

impl Drop for GeometryHandle {
    fn drop(&mut self) {
        // SAFETY: releases the one reference this handle owns.
        unsafe { raw::rtcReleaseGeometry(self.0.as_ptr()) }
    }
}

/// Meshes instanced into a top-level scene, committed and ready for queries.
///
/// Each mesh is built once into its own bottom-level scene (high build
/// quality: it is reused for every scene time). Changing the transforms
/// only rebuilds the small top-level hierarchy over the instances.
/// Instance `i` has Embree geometry id `i`, which queries report in
/// `hit.instID[0]`.
pub struct InstancedScene {
    top: SceneHandle,
    instances: Vec<GeometryHandle>,
    // Embree's instances keep their scenes alive too; holding them here
    // states the ownership instead of relying on that.
    _meshes: Vec<SceneHandle>,
    device: Device,
}

// SAFETY: every Embree handle held here may be used and released from any
// thread; nothing is tied to the creating thread.
unsafe impl Send for InstancedScene {}
// SAFETY: the scene is committed whenever a `&InstancedScene` exists
// (construction commits, and `set_transforms` takes `&mut self` and commits
// before returning). Embree documents `rtcIntersect*` and `rtcOccluded*` on a
// committed scene as safe to call from many threads at once; those are the
// only calls `&self` methods make.
unsafe impl Sync for InstancedScene {}

impl InstancedScene {
    /// Builds one bottom-level scene per mesh (vertex and index data are
    /// copied into Embree's own buffers, so the meshes need not outlive the
    /// scene) and instances mesh `i` with `transforms[i]`.
    pub fn new(device: &Device, meshes: &[MeshGeometry], transforms: &[Affine3A]) -> Result<Self> {
        ensure!(
            meshes.len() == transforms.len(),
            "{} meshes but {} transforms",
            meshes.len(),
            transforms.len()
        );
        ensure!(
            u32::try_from(meshes.len()).is_ok_and(|n| n < INVALID_ID),
            "too many meshes for Embree: {}",
            meshes.len()
        );
        let mut mesh_scenes = Vec::with_capacity(meshes.len());
        for (i, mesh) in meshes.iter().enumerate() {
            let scene = build_mesh_scene(device, mesh).with_context(|| format!("mesh {i}"))?;
            mesh_scenes.push(scene);
        }
        let top = SceneHandle::new(device, raw::RTCBuildQuality::RTC_BUILD_QUALITY_MEDIUM)?;
        let mut instances = Vec::with_capacity(meshes.len());
        for (i, mesh_scene) in mesh_scenes.iter().enumerate() {
            let instance =
                GeometryHandle::new(device, raw::RTCGeometryType::RTC_GEOMETRY_TYPE_INSTANCE)?;
            // SAFETY: both handles are valid; the top scene is not committed
            // yet, so attaching cannot race with queries. `i` fits in u32
            // (checked above).
            unsafe {
                raw::rtcSetGeometryInstancedScene(instance.0.as_ptr(), mesh_scene.0.as_ptr());
                raw::rtcAttachGeometryByID(top.0.as_ptr(), instance.0.as_ptr(), i as u32);
            }
            device.check(|| format!("instance mesh {i}"))?;
            instances.push(instance);
        }
        let mut scene = Self {
            top,
            instances,
            _meshes: mesh_scenes,
            device: device.clone(),
        };
        scene.set_transforms(transforms)?;
        Ok(scene)
    }

    /// Places instance `i` with `transforms[i]` and recommits the top-level
    /// scene; the meshes' own hierarchies are untouched.
    pub fn set_transforms(&mut self, transforms: &[Affine3A]) -> Result<()> {
        ensure!(
            transforms.len() == self.instances.len(),
            "{} transforms for {} instances",
            transforms.len(),
            self.instances.len()
        );
        // Every transform is checked before any is handed to Embree, so a
        // refused set leaves the committed scene as it was.
        if let Some(i) = transforms.iter().position(|x| !x.is_finite()) {
            bail!("transform {i} is not finite: {:?}", transforms[i]);
        }
        for (i, (instance, xfm)) in self.instances.iter().zip(transforms).enumerate() {
            // Affine3A's column-major 3x4 layout is Embree's FLOAT3X4_COLUMN_MAJOR.
            let cols = xfm.to_cols_array();
            // SAFETY: the geometry is a valid instance; `cols` holds the 12
            // floats the format reads; `&mut self` excludes concurrent queries.
            unsafe {
                raw::rtcSetGeometryTransform(
                    instance.0.as_ptr(),
                    0,
                    raw::RTCFormat::RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR,
                    cols.as_ptr().cast(),
                );
                raw::rtcCommitGeometry(instance.0.as_ptr());
            }
            self.device
                .check(|| format!("set the transform of instance {i}"))?;
        }
        self.top.commit(&self.device, "the top-level scene")
    }

    /// Embree's error state after queries on this thread, once per batch:
    /// the query calls return nothing, so an error there (out of memory, an
    /// argument Embree refuses) would otherwise go unseen.
    pub fn check_queries(&self) -> Result<()> {
        self.device.check(|| "trace rays".to_string())
    }

    /// Closest hit of one ray: on return `rayhit.hit.geomID` is
    /// [`INVALID_ID`] for a miss, else `ray.tfar` is the hit distance and
    /// `hit` describes it (`Ng` in the instanced mesh's object space).
    #[inline]
    pub fn intersect1(&self, rayhit: &mut raw::RTCRayHit) {
        let mut ctx = context(raw::RTCIntersectContextFlags::RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
        // SAFETY: the scene is committed (see `Sync`); `ctx` and `rayhit`
        // are valid, exclusive, and correctly aligned (bindgen's layout
        // checks hold `RTCRayHit` to 16 bytes); `rtcIntersect1` takes
        // (scene, context, rayhit).
        unsafe {
            call_ftz(
                raw::rtcIntersect1 as *const (),
                [
                    self.top.0.as_ptr() as usize,
                    &raw mut ctx as usize,
                    rayhit as *mut raw::RTCRayHit as usize,
                    0,
                ],
            )
        }
    }

    /// Whether anything blocks the ray: on return `ray.tfar` is `-inf` if so.
    #[inline]
    pub fn occluded1(&self, ray: &mut raw::RTCRay) {
        let mut ctx = context(raw::RTCIntersectContextFlags::RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
        // SAFETY: as in `intersect1`; `rtcOccluded1` takes (scene, context, ray).
        unsafe {
            call_ftz(
                raw::rtcOccluded1 as *const (),
                [
                    self.top.0.as_ptr() as usize,
                    &raw mut ctx as usize,
                    ray as *mut raw::RTCRay as usize,
                    0,
                ],
            )
        }
    }

    /// `intersect1` for the active lanes of a 16-ray packet.
    ///
    /// Packets are always traced with the incoherent flag: Embree 3.13.5's
    /// coherent (frustum) packet traversal of instanced robust scenes looped
    /// forever on shadow rays of a Cornell box, and was slower than the
    /// incoherent one on the shadow rays measured.
    #[inline]
    pub fn intersect16(&self, valid: &Valid16, rayhit: &mut raw::RTCRayHit16) {
        let mut ctx = context(raw::RTCIntersectContextFlags::RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
        // SAFETY: as in `intersect1`; `valid` and `rayhit` have the 64-byte
        // alignment Embree requires (their types guarantee it);
        // `rtcIntersect16` takes (valid, scene, context, rayhit).
        unsafe {
            call_ftz(
                raw::rtcIntersect16 as *const (),
                [
                    valid.0.as_ptr() as usize,
                    self.top.0.as_ptr() as usize,
                    &raw mut ctx as usize,
                    rayhit as *mut raw::RTCRayHit16 as usize,
                ],
            )
        }
    }

    /// `occluded1` for the active lanes of a 16-ray packet, incoherent for
    /// the reason given at [`Self::intersect16`].
    #[inline]
    pub fn occluded16(&self, valid: &Valid16, ray: &mut raw::RTCRay16) {
        let mut ctx = context(raw::RTCIntersectContextFlags::RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
        // SAFETY: as in `intersect16`; `rtcOccluded16` takes (valid, scene,
        // context, ray).
        unsafe {
            call_ftz(
                raw::rtcOccluded16 as *const (),
                [
                    valid.0.as_ptr() as usize,
                    self.top.0.as_ptr() as usize,
                    &raw mut ctx as usize,
                    ray as *mut raw::RTCRay16 as usize,
                ],
            )
        }
    }

    /// The baseline a wrapper is measured against: a bare `rtcIntersect1`
    /// loop (default floating-point mode, no result conversion). Returns how
    /// many rays hit something.
    pub fn count_hits(&self, rays: &[Ray]) -> u32 {
        let scene = self.top.0.as_ptr();
        let mut ctx = context(raw::RTCIntersectContextFlags::RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
        let mut hits = 0;
        for r in rays {
            let mut rayhit = ray_hit(r);
            // SAFETY: as in `intersect1`.
            unsafe { raw::rtcIntersect1(scene, &mut ctx, &mut rayhit) };
            hits += u32::from(rayhit.hit.geomID != INVALID_ID);
        }
        hits
    }

    /// The baseline for occlusion: a bare `rtcOccluded1` loop. Returns how
    /// many rays are blocked.
    pub fn count_occluded(&self, rays: &[Ray]) -> u32 {
        let scene = self.top.0.as_ptr();
        let mut ctx = context(raw::RTCIntersectContextFlags::RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
        let mut blocked = 0;
        for r in rays {
            let mut ray = ray1(r);
            // SAFETY: as in `occluded1`.
            unsafe { raw::rtcOccluded1(scene, &mut ctx, &mut ray) };
            blocked += u32::from(ray.tfar == f32::NEG_INFINITY);
        }
        blocked
    }
}

/// A mesh's own committed scene with one triangle geometry (id 0), or none
/// for a mesh without triangles.
fn build_mesh_scene(device: &Device, mesh: &MeshGeometry) -> Result<SceneHandle> {
    let nverts = mesh.positions.len();
    ensure!(
        u32::try_from(nverts).is_ok(),
        "{nverts} vertices exceed Embree's 32-bit indices"
    );
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if let Some(&bad) = tri.iter().find(|&&k| k as usize >= nverts) {
            anyhow::bail!("triangle {t} has vertex index {bad} but the mesh has {nverts} vertices");
        }
    }
    let scene = SceneHandle::new(device, raw::RTCBuildQuality::RTC_BUILD_QUALITY_HIGH)?;
    if !mesh.triangles.is_empty() {
        let geometry =
            GeometryHandle::new(device, raw::RTCGeometryType::RTC_GEOMETRY_TYPE_TRIANGLE)?;
        let g = geometry.0.as_ptr();
        // SAFETY: `g` is a valid triangle geometry. Embree allocates each
        // buffer for `count` items of `stride` bytes (plus the padding it
        // needs for vector loads) or returns null with an error, checked
        // before anything is written.
        let (vbuf, ibuf) = unsafe {
            let vbuf = raw::rtcSetNewGeometryBuffer(
                g,
                raw::RTCBufferType::RTC_BUFFER_TYPE_VERTEX,
                0,
                raw::RTCFormat::RTC_FORMAT_FLOAT3,
                size_of::<Vec3>(),
                nverts,
            );
            let ibuf = raw::rtcSetNewGeometryBuffer(
                g,
                raw::RTCBufferType::RTC_BUFFER_TYPE_INDEX,
                0,
                raw::RTCFormat::RTC_FORMAT_UINT3,
                size_of::<[u32; 3]>(),
                mesh.triangles.len(),
            );
            (vbuf, ibuf)
        };
        device.check(|| "allocate vertex and index buffers".into())?;
        ensure!(
            !vbuf.is_null() && !ibuf.is_null(),
            "Embree returned no buffer"
        );
        // SAFETY: the buffers hold exactly `nverts` FLOAT3 and
        // `triangles.len()` UINT3 items, tightly packed like `Vec3` (three
        // f32, `repr(C)`) and `[u32; 3]`; Embree's allocations are aligned
        // for f32/u32 and do not overlap the meshes' vectors.
        unsafe {
            std::ptr::copy_nonoverlapping(mesh.positions.as_ptr(), vbuf.cast::<Vec3>(), nverts);
            std::ptr::copy_nonoverlapping(
                mesh.triangles.as_ptr(),
                ibuf.cast::<[u32; 3]>(),
                mesh.triangles.len(),
            );
            raw::rtcCommitGeometry(g);
            raw::rtcAttachGeometryByID(scene.0.as_ptr(), g, 0);
        }
        device.check(|| "commit the triangle geometry".into())?;
    }
    scene.commit(device, "the mesh scene")?;
    Ok(scene)
}

/// `rtcInitIntersectContext`, an inline function in the header that bindgen
/// does not translate.
fn context(flags: raw::RTCIntersectContextFlags) -> raw::RTCIntersectContext {
    raw::RTCIntersectContext {
        flags,
        filter: None,
        instID: [INVALID_ID; raw::RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
    }
}

/// Embree's form of a ray segment.
#[inline]
pub fn ray1(r: &Ray) -> raw::RTCRay {
    raw::RTCRay {
        org_x: r.origin.x,
        org_y: r.origin.y,
        org_z: r.origin.z,
        tnear: r.tmin,
        dir_x: r.dir.x,
        dir_y: r.dir.y,
        dir_z: r.dir.z,
        time: 0.0,
        tfar: r.tmax,
        mask: u32::MAX,
        id: 0,
        flags: 0,
    }
}

/// A ray ready for `intersect1`, with the hit marked "none yet".
#[inline]
pub fn ray_hit(r: &Ray) -> raw::RTCRayHit {
    raw::RTCRayHit {
        ray: ray1(r),
        hit: raw::RTCHit {
            geomID: INVALID_ID,
            instID: [INVALID_ID; raw::RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
            ..Default::default()
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embree_errors_carry_embree_message() {
        let device = Device::new().unwrap();
        let geometry =
            GeometryHandle::new(&device, raw::RTCGeometryType::RTC_GEOMETRY_TYPE_TRIANGLE).unwrap();
        // SAFETY: a valid geometry; 1000 time steps exceed Embree's limit
        // (129), which it reports as an invalid argument.
        unsafe { raw::rtcSetGeometryTimeStepCount(geometry.0.as_ptr(), 1000) };
        let msg = format!(
            "{:#}",
            device.check(|| "set 1000 time steps".into()).unwrap_err()
        );
        assert!(msg.contains("set 1000 time steps"), "{msg}");
        assert!(msg.contains("invalid argument"), "{msg}");
        assert!(
            msg.contains("number of time steps is out of range"),
            "{msg}"
        );
        // Through the wrapper: Embree's own message reaches the caller.
        let err = SceneHandle::new(&device, raw::RTCBuildQuality(99))
            .err()
            .expect("build quality 99 does not exist");
        let msg = format!("{err:#}");
        assert!(msg.contains("invalid build quality"), "{msg}");
        // Each error was consumed: the next call on this thread is clean.
        assert!(SceneHandle::new(&device, raw::RTCBuildQuality::RTC_BUILD_QUALITY_LOW).is_ok());
    }

    #[test]
    fn errors_stay_on_the_thread_that_caused_them() {
        let device = Device::new().unwrap();
        let failing = device.clone();
        std::thread::spawn(move || {
            // SAFETY: a valid device and an out-of-range build quality, which
            // Embree rejects with an error recorded for this thread only.
            let scene = unsafe {
                let scene = raw::rtcNewScene(failing.as_raw());
                raw::rtcSetSceneBuildQuality(scene, raw::RTCBuildQuality(99));
                scene
            };
            assert!(failing.check(|| "set quality 99".into()).is_err());
            // SAFETY: releases the scene created above.
            unsafe { raw::rtcReleaseScene(scene) };
        })
        .join()
        .unwrap();
        assert!(device.check(|| "nothing".into()).is_ok());
    }

    fn unit_triangle() -> MeshGeometry {
        MeshGeometry {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            triangles: vec![[0, 1, 2]],
        }
    }

    #[test]
    fn non_finite_transforms_are_refused() {
        let device = Device::new().unwrap();
        let mesh = unit_triangle();
        let mut scene = InstancedScene::new(&device, &[mesh], &[Affine3A::IDENTITY]).unwrap();
        let bad = Affine3A::from_translation(Vec3::new(f32::NAN, 0.0, 0.0));
        let msg = format!("{:#}", scene.set_transforms(&[bad]).unwrap_err());
        assert!(msg.contains("transform 0"), "{msg}");
    }

    /// A set with one bad transform changes nothing: the instance before it
    /// is not moved, and the scene stays committed and queryable.
    #[test]
    fn a_refused_set_of_transforms_leaves_the_scene_as_it_was() {
        let device = Device::new().unwrap();
        let mesh = unit_triangle();
        let meshes = [mesh.clone(), mesh];
        let far = Affine3A::from_translation(Vec3::new(0.0, 0.0, 100.0));
        let mut scene = InstancedScene::new(&device, &meshes, &[Affine3A::IDENTITY, far]).unwrap();
        let moved = Affine3A::from_translation(Vec3::new(5.0, 0.0, 0.0));
        let bad = Affine3A::from_translation(Vec3::new(f32::NAN, 0.0, 0.0));
        let msg = format!("{:#}", scene.set_transforms(&[moved, bad]).unwrap_err());
        assert!(msg.contains("transform 1"), "{msg}");
        let trace = |x: f32| {
            let mut rh = ray_hit(&Ray::new(Vec3::new(x, 0.25, -1.0), Vec3::Z));
            scene.intersect1(&mut rh);
            (rh.hit.geomID != INVALID_ID).then_some(rh.hit.instID[0])
        };
        assert_eq!(trace(0.25), Some(0), "instance 0 left its place");
        assert_eq!(trace(5.25), None, "instance 0 moved by a refused set");
        scene.check_queries().unwrap();
    }

    /// An Embree error left on this thread is what a batch's check reports.
    #[test]
    fn query_checks_report_embree_errors() {
        let device = Device::new().unwrap();
        let mesh = unit_triangle();
        let scene = InstancedScene::new(&device, &[mesh], &[Affine3A::IDENTITY]).unwrap();
        scene.check_queries().unwrap();
        let geometry =
            GeometryHandle::new(&device, raw::RTCGeometryType::RTC_GEOMETRY_TYPE_TRIANGLE).unwrap();
        // SAFETY: a valid geometry; 1000 time steps exceed Embree's limit.
        unsafe { raw::rtcSetGeometryTimeStepCount(geometry.0.as_ptr(), 1000) };
        let msg = format!("{:#}", scene.check_queries().unwrap_err());
        assert!(
            msg.contains("trace rays") && msg.contains("invalid argument"),
            "{msg}"
        );
        scene.check_queries().unwrap();
    }
}
