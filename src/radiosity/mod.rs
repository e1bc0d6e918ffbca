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

use anyhow::{ensure, Result};
use glam::Vec3;

pub mod bake;
pub mod formfactor;
pub mod lookup;
pub mod simplify;
pub mod solver;
pub mod temporal;

pub use simplify::simplify;
pub use solver::solve;

/// The user's quality `q ∈ [0, 1]`: every subdivision decision of the
/// object-space stages follows from it (higher is finer and slower).
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd)]
pub struct Quality(f32);

impl Quality {
    pub fn new(q: f32) -> Result<Self> {
        ensure!((0.0..=1.0).contains(&q), "quality {q} is outside [0, 1]");
        Ok(Self(q))
    }

    pub fn get(self) -> f32 {
        self.0
    }
}

/// One planar triangle of the simplified scene, in its object's space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Patch {
    pub object: u32,
    /// Object-space corners; the winding gives the front side.
    pub vertices: [Vec3; 3],
    /// The records at the three corners (indices into
    /// [`Simplified::records`]); patches that share an edge in one plane
    /// share its records, which makes the output continuous there.
    pub corners: [u32; 3],
    /// Diffuse albedo (textures averaged, the specular part of glossy
    /// materials and mirrors left to the renderer's traced rays).
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
