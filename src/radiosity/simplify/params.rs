//! How the quality `q` becomes the simplification's thresholds (the table in
//! `docs/simplification.md` is the reference for these formulas).

use super::super::Quality;

/// Every threshold of one simplification, derived from the quality and the
/// scene's size so that the same `q` gives the same result at any scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    /// Diagonal of the scene's bounds at the start of the animation: the
    /// "average size of the environment" that sizes are compared against.
    pub scene_size: f32,
    /// No patch edge is longer than this (world units; object space of
    /// objects at unit scale). It is also the minimum size a surface is cut
    /// down to: edges at or below it are never split.
    pub max_edge: f32,
    /// The area one patch stands for (`max_edge² / 4`, what longest-edge
    /// bisection to `max_edge` leaves on average). Objects smaller than half
    /// of it are pruned; objects whose triangles are smaller are coarsened.
    pub patch_area: f32,
    /// Bisection levels allowed per input triangle, a guard against slivers
    /// that halving the longest edge shortens only slowly.
    pub max_depth: u32,
    /// Rays shot from the view space to count hits per object.
    pub visibility_rays: u64,
    /// Objects hit by fewer than this fraction of the rays that hit anything
    /// are left out (unseen objects always are).
    pub rare_share: f64,
    /// Objects hit by fewer than this fraction are coarsened further.
    pub moderate_share: f64,
    /// The share of their area-based triangle budget moderately seen objects
    /// keep.
    pub moderate_keep: f32,
    /// meshopt's error bound for coarsening, relative to an object's extent.
    pub coarsen_error: f32,
}

/// Viewpoints per random time and random times (for an animated scene; a
/// static one uses all viewpoints at its one time).
pub const TRIALS: usize = 8;
pub const VIEWS_PER_TRIAL: usize = 8;

impl Params {
    pub fn new(quality: Quality, scene_size: f32) -> Params {
        let q = quality.get();
        // Eight patches along the scene's diagonal at q = 0, 64 at q = 1.
        let max_edge = scene_size * (-(3.0 + 3.0 * q)).exp2();
        let halvings = (scene_size / max_edge).log2().ceil() as u32;
        let qd = f64::from(q);
        Params {
            scene_size,
            max_edge,
            patch_area: 0.25 * max_edge * max_edge,
            max_depth: 4 * halvings + 8,
            visibility_rays: ((1u64 << 15) as f64 * (1.0 + 7.0 * qd)).round() as u64,
            rare_share: 2e-4 * (1.0 - qd) * (1.0 - qd),
            moderate_share: 1e-2 * (1.0 - qd),
            moderate_keep: 0.25 + 0.5 * q,
            coarsen_error: 0.02 + 0.08 * (1.0 - q),
        }
    }
}
