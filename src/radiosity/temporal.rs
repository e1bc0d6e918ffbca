//! Temporal decomposition of indirect illumination (paper §5.1.2).

use anyhow::Result;
use glam::Vec3;

use super::{IndirectSolution, Quality, Simplified};
use crate::accel::InstancedEngine;
use crate::scene::Scene;

/// Solutions at the times chosen by recursive bisection, in time order.
#[derive(Clone, Debug, PartialEq)]
pub struct TimeSeries {
    pub times: Vec<f32>,
    pub solutions: Vec<IndirectSolution>,
}

impl TimeSeries {
    /// Per-record indirect irradiance at `t`, linear between the bracketing
    /// solutions and held outside them.
    pub fn indirect_at(&self, t: f32) -> Vec<Vec3> {
        let _ = t;
        todo!("time interpolation")
    }
}

/// Solves at the ends of the animation and bisects while the two ends of an
/// interval disagree by more than `quality` allows. A static scene gets one
/// solution.
pub fn decompose(
    scene: &Scene,
    simplified: &Simplified,
    engine: &mut dyn InstancedEngine,
    quality: Quality,
) -> Result<TimeSeries> {
    let _ = (scene, simplified, engine, quality);
    todo!("temporal decomposition")
}
