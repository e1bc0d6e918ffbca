//! `rangewalk export`: the scene at one time for another renderer.

use std::path::PathBuf;

use anyhow::Result;
use rangewalk::export::mitsuba;
use rangewalk::{image, output};

use super::camera::CameraArgs;
use super::{choice, load};

/// The renderers a scene is written for.
#[derive(
    Clone, Copy, strum::EnumString, strum::IntoStaticStr, strum::VariantArray, strum::EnumMessage,
)]
#[strum(serialize_all = "lowercase")]
pub enum ExportFormat {
    Mitsuba,
}

/// `rangewalk export`.
#[derive(clap::Args)]
pub struct ExportArgs {
    scene: PathBuf,
    #[command(flatten)]
    camera: CameraArgs,
    #[arg(long, default_value_t = 64)]
    spp: u32,
    #[arg(long)]
    max_depth: Option<u32>,
    #[arg(long, value_parser = choice::<ExportFormat>())]
    format: ExportFormat,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
}

pub fn run(args: ExportArgs) -> Result<()> {
    let ExportArgs {
        scene,
        camera: view,
        spp,
        max_depth,
        format,
        out,
    } = args;
    image::check_output_dir("--out", &out)?;
    output::check_only(&out, &mitsuba::CONTENTS)?;
    let s = load(&scene)?;
    view.check_time(&s)?;
    let camera = view.camera(&s)?;
    match format {
        ExportFormat::Mitsuba => mitsuba::export(&s, view.time, &camera, spp, max_depth, &out)?,
    }
    println!(
        "{}: Mitsuba 3 scene at t = {} s",
        out.join("scene.xml").display(),
        view.time
    );
    Ok(())
}
