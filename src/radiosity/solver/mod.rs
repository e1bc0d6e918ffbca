//! Hierarchical radiosity on the simplified scene.

use anyhow::Result;

use super::{IndirectSolution, Quality, Simplified};
use crate::accel::RayEngine;
use crate::scene::Scene;

/// Indirect irradiance at every record of `simplified` at `time`. `engine`
/// holds the full scene posed at `time` (occluders include what the
/// simplification left out).
pub fn solve(
    scene: &Scene,
    simplified: &Simplified,
    engine: &dyn RayEngine,
    time: f32,
    quality: Quality,
) -> Result<IndirectSolution> {
    let _ = (scene, simplified, engine, time, quality);
    todo!("hierarchical radiosity")
}
