//! The `view` command: the interactive walk-through's options.

use std::path::PathBuf;

use anyhow::Result;
use rangewalk::image;
use rangewalk::viewer::command::{self, Moving, ViewSettings};

use super::choice;
use super::synth::SynthOptions;

/// `rangewalk view`.
#[derive(clap::Args, Clone, Debug)]
pub struct ViewArgs {
    /// A complete bake directory (`rangewalk bake`).
    pub bake: PathBuf,
    /// Window size at the start, `<W>x<H>`; frames follow the window's size.
    #[arg(long, default_value = "512x512", value_parser = image::parse_size)]
    pub size: (u32, u32),
    /// Named camera of the scene to start at [default: the scene's first].
    #[arg(long)]
    pub camera: Option<String>,
    /// Scene time to start at [default: the animation's start].
    #[arg(long, allow_negative_numbers = true)]
    pub time: Option<f32>,
    /// Play this walk path of the scene, looping: the viewer takes its
    /// pose and time at every frame.
    #[arg(long, conflicts_with = "input")]
    pub path: Option<String>,
    /// Scripted input, one step a line: `<frames> [key ...] [drag <dx>,<dy>]`
    /// (keys: w a s d q e left right up down space comma period home f t shift).
    #[arg(long)]
    pub input: Option<PathBuf>,
    /// Stop after this many frames [scripted default: the script's length,
    /// or one loop of the path].
    #[arg(long)]
    pub frames: Option<usize>,
    /// Save the last frame shown (status lines included) as PNG.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Save every frame shown as `frame-NNNN.png` in this folder.
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// Moving speed in scene units per second [default: a quarter of the
    /// view space's longest side per second].
    #[arg(long)]
    pub speed: Option<f32>,
    /// Scene frames per second of a scripted run [default: the scene's].
    #[arg(long)]
    pub fps: Option<f32>,
    /// How frames are made while the view or the time changes.
    #[arg(long, value_parser = choice::<Moving>(), default_value_t = Moving::default())]
    pub moving: Moving,
    #[command(flatten)]
    pub synth: SynthOptions,
}

impl ViewArgs {
    fn settings(&self) -> Result<ViewSettings> {
        Ok(ViewSettings {
            bake: self.bake.clone(),
            scene: self.synth.scene.clone(),
            size: self.size,
            camera: self.camera.clone(),
            time: self.time,
            path: self.path.clone(),
            input: self.input.clone(),
            frames: self.frames,
            screenshot: self.screenshot.clone(),
            record: self.record.clone(),
            speed: self.speed,
            fps: self.fps,
            options: self.synth.options(self.size)?,
            moving: self.moving,
            base_memory_bytes: self.synth.base_memory_bytes()?,
            exposure: self.synth.exposure,
        })
    }
}

pub fn view(args: &ViewArgs) -> Result<()> {
    let s = command::run(&args.settings()?)?;
    let last = s.last.as_ref();
    println!(
        "{} frame(s) ({} draft(s)) at {}: {:.1} frames/s synthesis, {:.1} frames/s shown, {:.3} s reading bases{}",
        s.frames,
        s.drafts,
        last.map_or("no size".into(), |r| format!(
            "{}x{} from {} base image(s) of view(s) {}",
            r.request.camera.width,
            r.request.camera.height,
            r.stats.images.len(),
            command::list(&r.views)
        )),
        s.synthesis_fps,
        s.shown_fps,
        s.load_seconds,
        args.screenshot
            .as_ref()
            .map_or(String::new(), |p| format!("; screenshot {}", p.display()))
    );
    if let Some(r) = last {
        let c = &r.request.camera;
        println!(
            "last frame: position {}, direction {}, t = {} s{}",
            c.position,
            c.forward,
            r.request.time,
            if s.at_edge {
                ", stopped at the view space's edge"
            } else {
                ""
            }
        );
    }
    Ok(())
}
