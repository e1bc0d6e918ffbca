//! Geometric simplification for the radiosity solver (paper §4.3).

use anyhow::Result;

use super::{Quality, Simplified};
use crate::accel::InstancedEngine;
use crate::scene::Scene;

/// Simplifies `scene` for radiosity at `quality`. `engine` holds the full
/// scene; it is moved to random times to measure visibility from the view
/// space and is left posed at an unspecified time.
pub fn simplify(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    quality: Quality,
) -> Result<Simplified> {
    let _ = (scene, engine, quality);
    todo!("simplification")
}
