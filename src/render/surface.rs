//! Light at surface points found without a camera ray: the points of a
//! synthesized frame, reprojected from base images and moved to the frame's
//! time. Re-shading them with the scene posed at that time is what makes a
//! moving shadow move instead of cross-fading between two base times.

use anyhow::{ensure, Result};
use glam::{Affine3A, Vec2, Vec3};

use super::lights::Lights;
use crate::accel::{Hit, RayEngine};
use crate::bsdf::{Frame, Lobes};
use crate::ray::{offset_origin, Ray};
use crate::rng::Pcg32;
use crate::scene::{Bsdf, Scene};

/// A point on triangle `primitive` of `object`, at the shading time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    pub object: u32,
    pub primitive: u32,
    /// World position at the shading time.
    pub position: Vec3,
    /// Unit direction from the point towards the viewer.
    pub wo: Vec3,
}

/// Where and how a point's diffuse lobe reflects light arriving from all
/// around: the object-space point, winding normal (turned to the viewer's
/// side) and side at which irradiance records are looked up, as the
/// multipass renderer looks them up at its hits, and the lobe's albedo.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffuseQuery {
    pub object: u32,
    pub front: bool,
    pub local: Vec3,
    pub normal: Vec3,
    pub albedo: Vec3,
}

/// What a mirror at a point reflects.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reflected {
    /// The reflected ray meets a surface: its hit and world point.
    Surface { hit: Hit, position: Vec3 },
    /// The reflected ray leaves the scene; the radiance it finds there
    /// (the sun's disk or nothing).
    Sky(Vec3),
}

/// The scene's lights and poses at one time, for shading given points.
pub struct SurfaceShading<'a> {
    scene: &'a Scene,
    engine: &'a dyn RayEngine,
    lights: Lights,
    poses: Vec<Affine3A>,
    inverse: Vec<Affine3A>,
}

/// The triangle under a point: its winding normal (world), its texture
/// coordinates where the mesh has them.
struct Local {
    ng: Vec3,
    uv: Option<Vec2>,
}

impl<'a> SurfaceShading<'a> {
    /// `engine` must hold the scene posed at `time`.
    pub fn new(scene: &'a Scene, engine: &'a dyn RayEngine, time: f32) -> Self {
        let poses = scene.at(time);
        let inverse = poses.iter().map(|p| p.inverse()).collect();
        Self {
            scene,
            engine,
            lights: Lights::new(scene, time),
            poses,
            inverse,
        }
    }

    fn local(&self, sp: &SurfacePoint) -> Option<Local> {
        let object = self.scene.objects.get(sp.object as usize)?;
        let [ia, ib, ic] = *object.mesh.triangles.get(sp.primitive as usize)?;
        let pos = &object.mesh.positions;
        let (a, b, c) = (pos[ia as usize], pos[ib as usize], pos[ic as usize]);
        let pose = self.poses[sp.object as usize];
        let ng = pose
            .transform_vector3((b - a).cross(c - a))
            .normalize_or_zero();
        if ng == Vec3::ZERO {
            return None;
        }
        let uv = object.mesh.uvs.as_ref().and_then(|uvs| {
            // Barycentrics of the object-space point in its triangle.
            let q = self.inverse[sp.object as usize].transform_point3(sp.position);
            let (e1, e2, d) = (b - a, c - a, q - a);
            let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
            let det = d11 * d22 - d12 * d12;
            if det == 0.0 {
                return None;
            }
            let (d1, d2) = (d.dot(e1), d.dot(e2));
            let u = (d22 * d1 - d12 * d2) / det;
            let v = (d11 * d2 - d12 * d1) / det;
            let uv = uvs[ia as usize] * (1.0 - u - v) + uvs[ib as usize] * u + uvs[ic as usize] * v;
            uv.is_finite().then_some(uv)
        });
        Some(Local { ng, uv })
    }

    /// Light the point's surface emits towards the viewer.
    pub fn emission(&self, sp: &SurfacePoint) -> Vec3 {
        let material = self.scene.material_of(sp.object);
        let (Some(em), Some(l)) = (material.emission, self.local(sp)) else {
            return Vec3::ZERO;
        };
        if em.two_sided || l.ng.dot(sp.wo) > 0.0 {
            em.radiance
        } else {
            Vec3::ZERO
        }
    }

    /// The point's [`DiffuseQuery`]; `None` where its material reflects
    /// nothing diffusely or the viewer sees its triangle edge-on.
    pub fn diffuse_query(&self, sp: &SurfacePoint) -> Option<DiffuseQuery> {
        let l = self.local(sp)?;
        let albedo = match Lobes::at(&self.scene.material_of(sp.object).bsdf, l.uv) {
            Lobes::Diffuse { albedo } => albedo,
            Lobes::Glossy { diffuse, .. } => diffuse,
            Lobes::Mirror { .. } => Vec3::ZERO,
        };
        let cos_o = l.ng.dot(sp.wo);
        if albedo == Vec3::ZERO || cos_o == 0.0 || !cos_o.is_finite() {
            return None;
        }
        let object = &self.scene.objects[sp.object as usize];
        let [a, b, c] =
            object.mesh.triangles[sp.primitive as usize].map(|i| object.mesh.positions[i as usize]);
        let n = (b - a).cross(c - a).normalize_or_zero();
        let front = cos_o > 0.0;
        Some(DiffuseQuery {
            object: sp.object,
            front,
            local: self.inverse[sp.object as usize].transform_point3(sp.position),
            normal: if front { n } else { -n },
            albedo,
        })
    }

    /// Direct light reflected towards the viewer by the diffuse lobe of each
    /// point's material: the mean of `samples` light samples per point
    /// (stratified when `samples` is a square), every shadow ray of the
    /// slice traced in one batch. `streams` holds each point's sampler
    /// stream (its pixel), so that a frame's result does not depend on how
    /// it is cut, and one pixel shaded at two times draws the same samples.
    pub fn diffuse_direct(
        &self,
        points: &[SurfacePoint],
        streams: &[u64],
        samples: u32,
        seed: u64,
    ) -> Result<Vec<Vec3>> {
        ensure!(
            points.len() == streams.len(),
            "{} points with {} sampler streams",
            points.len(),
            streams.len()
        );
        ensure!(samples > 0, "re-shading needs at least one light sample");
        let mut out = vec![Vec3::ZERO; points.len()];
        if self.lights.is_empty() {
            return Ok(out);
        }
        let strata = samples.isqrt();
        let mut rays = Vec::with_capacity(points.len() * samples as usize);
        let mut contrib = Vec::with_capacity(rays.capacity());
        for (i, sp) in points.iter().enumerate() {
            let Some(l) = self.local(sp) else { continue };
            let albedo = match Lobes::at(&self.scene.material_of(sp.object).bsdf, l.uv) {
                Lobes::Diffuse { albedo } => albedo,
                Lobes::Glossy { diffuse, .. } => diffuse,
                Lobes::Mirror { .. } => Vec3::ZERO,
            };
            if albedo == Vec3::ZERO {
                continue;
            }
            let cos_o = l.ng.dot(sp.wo);
            if cos_o == 0.0 || !cos_o.is_finite() {
                continue;
            }
            let n = if cos_o > 0.0 { l.ng } else { -l.ng };
            let frame = Frame::new(n);
            let wo_l = frame.to_local(sp.wo);
            let lobe = Lobes::Diffuse { albedo };
            for s in 0..samples {
                let mut rng = Pcg32::for_sample(seed, streams[i], s as u64);
                let (u, mut u1, mut u2) = (rng.next_f64(), rng.next_f32(), rng.next_f32());
                if strata > 1 && s < strata * strata {
                    let inv = 1.0 / strata as f32;
                    u1 = (((s % strata) as f32 + u1) * inv).min(1.0 - f32::EPSILON);
                    u2 = (((s / strata) as f32 + u2) * inv).min(1.0 - f32::EPSILON);
                }
                let Some(ls) = self.lights.sample(sp.position, l.ng, u, u1, u2) else {
                    continue;
                };
                let wi_l = frame.to_local(ls.wi);
                if wi_l.z <= 0.0 {
                    continue;
                }
                let c = lobe.eval(wo_l, wi_l) * ls.radiance * (wi_l.z / ls.pdf);
                if c.is_finite() && c != Vec3::ZERO {
                    rays.push(ls.shadow);
                    contrib.push((i, c / samples as f32));
                }
            }
        }
        let mut blocked = vec![false; rays.len()];
        self.engine.occluded_batch(&rays, &mut blocked);
        for ((i, c), blocked) in contrib.into_iter().zip(blocked) {
            if !blocked {
                out[i] += c;
            }
        }
        Ok(out)
    }

    /// For a point on a mirror: its reflectance and what the mirror
    /// reflects towards the viewer. `None` for other materials.
    pub fn mirror(&self, sp: &SurfacePoint) -> Option<(Vec3, Reflected)> {
        let Bsdf::Mirror { reflectance } = self.scene.material_of(sp.object).bsdf else {
            return None;
        };
        let l = self.local(sp)?;
        let n = if l.ng.dot(sp.wo) > 0.0 { l.ng } else { -l.ng };
        let wi = (2.0 * n.dot(sp.wo) * n - sp.wo).normalize_or_zero();
        if wi == Vec3::ZERO {
            return None;
        }
        let ray = Ray::new(offset_origin(sp.position, l.ng, wi), wi);
        let reflected = match self.engine.intersect(&ray) {
            Some(hit) => Reflected::Surface {
                hit,
                position: ray.at(hit.t),
            },
            None => Reflected::Sky(self.lights.sun_along(wi).map_or(Vec3::ZERO, |(le, _)| le)),
        };
        Some((reflectance, reflected))
    }
}
