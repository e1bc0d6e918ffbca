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
    /// objects at unit scale) unless the patch is a sliver of at most
    /// `min_patch_area`. Edges at or below it are never split.
    pub max_edge: f32,
    /// Patches are not split below this area (`patch_area / 4`): the
    /// paper's minimum patch size, which bounds what thin parts cost.
    pub min_patch_area: f32,
    /// The area one patch stands for (`max_edge² / 4`, what longest-edge
    /// bisection to `max_edge` leaves at most). Objects whose triangles are
    /// smaller are coarsened.
    pub patch_area: f32,
    /// Connected parts of objects (a book, a chair's knob) smaller than this
    /// are pruned: two patches' area at q = 0, half a patch at q = 1.
    pub min_part_area: f32,
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
}

/// Viewpoints per random time and random times (for an animated scene; a
/// static one uses all viewpoints at its one time).
pub const TRIALS: usize = 8;
pub const VIEWS_PER_TRIAL: usize = 8;

impl Params {
    pub fn new(quality: Quality, scene_size: f32) -> Params {
        let q = quality.get();
        // 8 patch edges along the scene's diagonal at q = 0, 23 at q = 1: a
        // room's surfaces then give about 1.5k to 7k patches, which the
        // solver links in about a second (finer ones cost time and changed
        // no record of the Cornell box by more than its Monte Carlo check's
        // scatter).
        let max_edge = scene_size * (-(3.0 + 1.5 * q)).exp2();
        let halvings = (scene_size / max_edge).log2().ceil() as u32;
        let qd = f64::from(q);
        Params {
            scene_size,
            max_edge,
            patch_area: 0.25 * max_edge * max_edge,
            min_patch_area: max_edge * max_edge / 16.0,
            min_part_area: 0.25 * max_edge * max_edge * (2.0 - 1.5 * q),
            max_depth: 4 * halvings + 8,
            visibility_rays: ((1u64 << 15) as f64 * (1.0 + 7.0 * qd)).round() as u64,
            rare_share: 2e-4 * (1.0 - qd) * (1.0 - qd),
            moderate_share: 1e-2 * (1.0 - qd),
            moderate_keep: 0.25 + 0.5 * q,
        }
    }
}
