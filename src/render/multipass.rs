//! The multipass renderer (paper §4.4): direct light ray traced, specular
//! and glossy reflection traced, diffuse indirect light looked up from the
//! radiosity records instead of traced.

use anyhow::Result;

use super::{RenderSettings, RenderStats};
use crate::accel::RayEngine;
use crate::camera::Camera;
use crate::image::RangeImage;
use crate::radiosity::lookup::IrradianceCache;
use crate::scene::Scene;

/// Renders `camera`'s view at `time`; `engine` holds the scene posed at
/// `time` and `indirect` the records interpolated to `time`.
/// `settings.max_depth` bounds the chain of specular bounces.
pub fn render(
    scene: &Scene,
    engine: &dyn RayEngine,
    camera: &Camera,
    time: f32,
    settings: &RenderSettings,
    indirect: &IrradianceCache,
) -> Result<(RangeImage, RenderStats)> {
    let _ = (scene, engine, camera, time, settings, indirect);
    todo!("multipass renderer")
}
