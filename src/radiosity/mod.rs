//! Indirect illumination in object space (paper §3.2.2, §4.3, §5.1).
//!
//! Indirect light changes slowly in space and in time, so it is computed
//! sparsely in both: on a simplified copy of the scene ([`simplify`]), by
//! hierarchical radiosity at a few times ([`solve`]) chosen by recursive
//! bisection of the animation ([`temporal`]), and interpolated linearly in
//! between. The result is a set of *irradiance records* attached to objects
//! in object space, so that they move with their objects; renderers look
//! them up ([`lookup`]) where a path tracer would have traced a diffuse
//! bounce. Only indirect light is stored: direct light is ray traced at
//! render time, where shadows stay sharp.
//!
//! Units: irradiance in W·m⁻² (of the scene's length unit), radiance in
//! W·m⁻²·sr⁻¹; a Lambertian surface of albedo ρ under irradiance `E` leaves
//! radiance `ρ E / π`.

use std::collections::HashMap;

use anyhow::Result;
use glam::Vec3;

use crate::bsdf::Lobes;
use crate::quality::Quality;
use crate::scene::{Bsdf, Scene};

pub mod formfactor;
pub mod lookup;
pub mod simplify;
pub mod solver;
pub mod store;
pub mod temporal;

pub use simplify::simplify;
pub use solver::solve;

/// The object-space stages end to end: the scene simplified, then solved at
/// the times the temporal decomposition picks.
pub fn simplify_and_decompose(
    scene: &Scene,
    engine: &mut dyn crate::accel::InstancedEngine,
    q: Quality,
) -> Result<(Simplified, temporal::TimeSeries)> {
    let simplified = simplify(scene, engine, q)?;
    let series = temporal::decompose(scene, &simplified, engine, q)?;
    Ok((simplified, series))
}

/// One planar triangle of the simplified scene, in its object's space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Patch {
    pub object: u32,
    /// Object-space corners; the winding gives the front side.
    pub vertices: [Vec3; 3],
    /// The records of the front side at the three corners (indices into
    /// [`Simplified::records`]); patches that share an edge in one plane
    /// share its records, which makes the output continuous there.
    pub corners: [u32; 3],
    /// The records of the back side (normal reversed). Every surface
    /// reflects on both sides, and which one a viewer sees is not known
    /// here: a wall lit by the sun outside is seen dark from inside. The
    /// same as `corners` where a record stands for both sides; it then
    /// reports the side that receives more light.
    pub back: [u32; 3],
    /// The share of incident light the surface reflects, carried on as
    /// diffuse light: see [`transport_albedo`].
    pub reflectance: Vec3,
    /// Emitted radiance, zero for non-emitters.
    pub emission: Vec3,
    /// Whether `emission` leaves both sides (else only the front).
    pub two_sided: bool,
}

/// A point where indirect irradiance is output: a patch corner, in its
/// object's space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecordPoint {
    pub object: u32,
    pub position: Vec3,
    /// Unit normal of the patches that share this record.
    pub normal: Vec3,
}

/// The paper's Table 1 (first half) for one quality.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SimplifyStats {
    /// Triangles of the input scene.
    pub initial_surfaces: usize,
    /// Input triangles left out (objects rarely seen, primitives too small).
    pub pruned_surfaces: usize,
    /// Patches handed to the radiosity solver.
    pub final_surfaces: usize,
    /// Rays traced to measure visibility from the view space.
    pub visibility_rays: u64,
    pub seconds: f64,
}

/// The scene as the radiosity solver sees it. Fixed for a whole animation:
/// every solution gives one irradiance per record, in this order, which is
/// what lets solutions at different times be interpolated.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Simplified {
    pub patches: Vec<Patch>,
    pub records: Vec<RecordPoint>,
    /// The input triangles no patch stands for (left-out objects, pruned
    /// parts) as `(object, index in its mesh)`, ascending. They still stand
    /// in the light, and a solver that let them only block it made them
    /// black: the studio's left-out books took 2.3% of its indirect light at
    /// q = 0.3 (docs/radiosity.md).
    pub pruned: Vec<(u32, u32)>,
    pub stats: SimplifyStats,
}

/// What one solve cost and how well it converged.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveStats {
    /// Leaf elements of the final hierarchy.
    pub elements: usize,
    pub links: usize,
    /// Solver iterations (summed over refinement rounds).
    pub iterations: usize,
    /// Final relative residual ‖b − A x‖ / ‖b‖ of the linear system.
    pub residual: f64,
    pub shadow_rays: u64,
    pub seconds: f64,
}

/// Indirect illumination of the simplified scene at one time.
#[derive(Clone, Debug, PartialEq)]
pub struct IndirectSolution {
    pub time: f32,
    /// Indirect irradiance at each record (light that has been reflected at
    /// least once before arriving).
    pub indirect: Vec<Vec3>,
    /// Direct irradiance at each record (from emitters, point lights and
    /// the sun, with shadows). Kept for checks and reports; renderers trace
    /// direct light themselves.
    pub direct: Vec<Vec3>,
    pub stats: SolveStats,
}

impl Patch {
    pub fn area(&self) -> f32 {
        let [a, b, c] = self.vertices;
        0.5 * (b - a).cross(c - a).length()
    }

    /// Unit normal of the front side, by winding.
    pub fn normal(&self) -> Vec3 {
        let [a, b, c] = self.vertices;
        (b - a).cross(c - a).normalize_or_zero()
    }

    /// The patch's corner records per side: the front's, then the back's
    /// unless the same records stand for both.
    pub fn sides(&self) -> impl Iterator<Item = [u32; 3]> {
        std::iter::once(self.corners).chain((self.back != self.corners).then_some(self.back))
    }
}

/// Which sides record `i` serves, as bits (1 front, 2 back): both where
/// one record stands for both sides of its patches, none where no patch
/// names it.
pub fn record_sides(s: &Simplified) -> Vec<u8> {
    let mut sides = vec![0u8; s.records.len()];
    for p in &s.patches {
        for (bit, set) in [(1u8, p.corners), (2, p.back)] {
            for i in set {
                if let Some(side) = sides.get_mut(i as usize) {
                    *side |= bit;
                }
            }
        }
    }
    sides
}

/// What radiosity carries on from a surface: all the light it reflects,
/// spread as if diffusely (textures averaged).
///
/// The glossy lobe and the mirror send their share in other directions,
/// which a diffuse solver cannot follow; but leaving it out makes such a
/// surface a sink, and a room lit mainly off a glossy floor renders too
/// dark everywhere (docs/radiosity.md, "The dark bias").
/// Only the transport uses this; shading at a rendered pixel applies
/// [`diffuse_albedo`] to the records' irradiance and traces the rest.
pub fn transport_albedo(bsdf: &Bsdf) -> Vec3 {
    match bsdf {
        Bsdf::Diffuse { .. } => diffuse_albedo(bsdf),
        _ => Lobes::at(bsdf, None).hemispherical_albedo(),
    }
}

/// The diffuse lobe's albedo (textures averaged): what the renderer
/// multiplies the records' irradiance by.
pub fn diffuse_albedo(bsdf: &Bsdf) -> Vec3 {
    match bsdf {
        Bsdf::Diffuse {
            reflectance,
            texture,
        } => match texture {
            Some(t) if !t.texels.is_empty() => {
                let sum: Vec3 = t.texels.iter().copied().sum();
                *reflectance * sum / t.texels.len() as f32
            }
            _ => *reflectance,
        },
        Bsdf::Glossy { diffuse, .. } => *diffuse,
        Bsdf::Mirror { .. } => Vec3::ZERO,
    }
}

impl Simplified {
    /// Every triangle of the scene as one patch, nothing left out: the exact
    /// geometry, for small scenes and as the baseline the simplification is
    /// measured against.
    pub fn whole(scene: &Scene) -> Simplified {
        let triangles = scene.objects.iter().enumerate().flat_map(|(i, o)| {
            o.mesh
                .triangles
                .iter()
                .map(move |t| (i as u32, t.map(|v| o.mesh.positions[v as usize])))
        });
        let mut s = Simplified::from_triangles(scene, triangles);
        s.stats.initial_surfaces = s.patches.len();
        s.stats.final_surfaces = s.patches.len();
        s
    }

    /// Patches from object-space triangles `(object, corners)`, with
    /// materials from `scene`. Corners of one object that coincide and face
    /// the same way share one pair of records (front, then back);
    /// zero-area triangles are skipped.
    /// Statistics are left for the caller to fill in.
    pub fn from_triangles(
        scene: &Scene,
        triangles: impl IntoIterator<Item = (u32, [Vec3; 3])>,
    ) -> Simplified {
        let mut records = Vec::new();
        let mut index: HashMap<(u32, [i64; 3], [i32; 3]), u32> = HashMap::new();
        let mut patches = Vec::new();
        let albedo: Vec<Vec3> = scene
            .materials
            .iter()
            .map(|m| transport_albedo(&m.bsdf))
            .collect();
        for (object, vertices) in triangles {
            let o = &scene.objects[object as usize];
            let m = &scene.materials[o.material];
            let mut patch = Patch {
                object,
                vertices,
                corners: [0; 3],
                back: [0; 3],
                reflectance: albedo[o.material],
                emission: m.emission.map_or(Vec3::ZERO, |e| e.radiance),
                two_sided: m.emission.is_some_and(|e| e.two_sided),
            };
            let n = patch.normal();
            if patch.area() <= 0.0 || !n.is_finite() || n == Vec3::ZERO {
                continue;
            }
            // Weld to a grid of 2^-20 of the object's extent: far finer than
            // any patch, coarse enough to merge copies of one OBJ vertex.
            let scale = object_extent(&o.mesh.positions) * (1.0 / (1u64 << 20) as f32);
            let qn = (n * 1000.0).round().as_ivec3().to_array();
            for (k, &p) in vertices.iter().enumerate() {
                let qp = (p / scale).round().as_i64vec3().to_array();
                let front = *index.entry((object, qp, qn)).or_insert_with(|| {
                    for normal in [n, -n] {
                        records.push(RecordPoint {
                            object,
                            position: p,
                            normal,
                        });
                    }
                    (records.len() - 2) as u32
                });
                patch.corners[k] = front;
                patch.back[k] = front + 1;
            }
            patches.push(patch);
        }
        Simplified {
            patches,
            records,
            pruned: Vec::new(),
            stats: SimplifyStats::default(),
        }
    }
}

pub(crate) fn object_extent(positions: &[Vec3]) -> f32 {
    let (lo, hi) = positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let e = (hi - lo).max_element();
    if e.is_finite() && e > 0.0 {
        e
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_cornell_box_shares_records_between_coplanar_triangles() {
        let scene = Scene::load(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/cornell-box/scene.toml"
        ))
        .unwrap();
        let s = Simplified::whole(&scene);
        let tris: usize = scene.objects.iter().map(|o| o.mesh.triangles.len()).sum();
        assert_eq!(s.patches.len(), tris);
        // The floor is one quad: two triangles, four corners, a front and a
        // back record at each.
        let floor: Vec<&Patch> = s.patches.iter().filter(|p| p.object == 0).collect();
        assert_eq!(floor.len(), 2);
        let mut corners: Vec<u32> = floor.iter().flat_map(|p| p.corners).collect();
        corners.sort();
        corners.dedup();
        assert_eq!(corners.len(), 4);
        for p in &floor {
            for k in 0..3 {
                let (f, b) = (
                    &s.records[p.corners[k] as usize],
                    &s.records[p.back[k] as usize],
                );
                assert_eq!(f.position, b.position);
                assert_eq!(f.normal, -b.normal);
                assert!(f.normal.dot(p.normal()) > 0.99);
            }
        }
        // A box's faces meet at right angles: no record is shared between
        // faces, so each of its 5 quads has 4 of its own.
        let short = s.patches.iter().filter(|p| p.object == 6);
        let mut c: Vec<u32> = short.flat_map(|p| p.corners).collect();
        c.sort();
        c.dedup();
        assert_eq!(c.len(), 20);
        for r in &s.records {
            assert!((r.normal.length() - 1.0).abs() < 1e-5);
        }
    }
}
