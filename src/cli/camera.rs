//! The camera of `render` and `export`: a named camera of the scene at a
//! time, size and projection.

use anyhow::{Context, Result};
use rangewalk::camera::{Camera, Projection};
use rangewalk::image;
use rangewalk::scene::Scene;

use super::choice;

#[derive(clap::Args)]
pub struct CameraArgs {
    /// Scene time in seconds (within the animation of an animated scene).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub time: f32,
    /// Named camera of the scene.
    #[arg(long, default_value = "main")]
    pub camera: String,
    /// Image size, `<W>x<H>`.
    #[arg(long, default_value = "256x256", value_parser = image::parse_size)]
    pub size: (u32, u32),
    /// Projection; the camera's field of view applies to `perspective` only.
    #[arg(long, value_parser = choice::<ProjectionName>(), default_value_t = ProjectionName::Perspective)]
    pub projection: ProjectionName,
}

/// The projections of a rendered frame, by name.
#[derive(
    Clone,
    Copy,
    strum::Display,
    strum::EnumString,
    strum::IntoStaticStr,
    strum::VariantArray,
    strum::EnumMessage,
)]
#[strum(serialize_all = "lowercase")]
pub enum ProjectionName {
    Perspective,
    Fisheye,
    Sphere,
}

impl CameraArgs {
    pub fn camera(&self, scene: &Scene) -> Result<Camera> {
        let desc = scene.camera(&self.camera)?;
        let (w, h) = self.size;
        match self.projection {
            ProjectionName::Perspective => desc.perspective(w, h),
            ProjectionName::Fisheye => desc.with_projection(Projection::Fisheye, w, h),
            ProjectionName::Sphere => desc.with_projection(Projection::Sphere, w, h),
        }
    }

    pub fn check_time(&self, scene: &Scene) -> Result<()> {
        scene.check_time(self.time).context("--time")
    }
}
