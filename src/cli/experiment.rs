//! `rangewalk experiment`: the options of the experiments that reproduce
//! the paper's tables, and the lines they print.

use std::path::PathBuf;

use anyhow::Result;
use rangewalk::accel::Backend;
use rangewalk::bake::IndirectSource;
use rangewalk::eval::experiments::common::sequence::SequenceQuality;
use rangewalk::eval::experiments::common::setup::{CommonArgs, SequenceArgs};
use rangewalk::eval::experiments::common::synthesize::mean_flip;
use rangewalk::eval::experiments::walkthrough::{self, BakeViews};
use rangewalk::eval::experiments::{indirect, motion, views};
use rangewalk::image;
use rangewalk::plan::ViewFitness;
use rangewalk::quality::Quality;
use rangewalk::scene::ViewSpace;
use rangewalk::synth::{Blend, Fill, TimeInterp};

use super::choice;

/// The experiments of `rangewalk experiment`.
#[derive(clap::Subcommand, Clone, Debug)]
pub enum Experiment {
    /// Indirect light from radiosity records in a multipass renderer against
    /// path-traced references, per quality, over the animation (paper
    /// Tables 1 and 2); writes table.md, frames.csv, convergence.csv, plots
    /// and previews.
    Indirect(Indirect),
    /// View reconstruction between base views along a 1D view subspace,
    /// per quality and fill mode, with the resampling error alone (paper
    /// Table 3); writes table.md, qualities.csv, plots and image strips.
    Views(Views),
    /// Object motion interpolated in time from base images at one fixed
    /// view, per quality and time interpolation (linear, motion
    /// compensated, re-shaded), every frame against a reference (paper
    /// Table 4); writes table.md, qualities.csv, frames.csv, plots and
    /// image strips.
    Motion(Motion),
    /// The whole framework (plan, simplification and radiosity, bake,
    /// synthesis) on a walk path, every phase timed, every frame against a
    /// path-traced frame, with the path tracer's time to the same error and
    /// the frames at which the bake pays, at equal LRMS and at equal FLIP
    /// (paper Table 5); writes table.md, qualities.csv, frames.csv,
    /// convergence.csv, plots and image strips.
    Walkthrough(Walkthrough),
}

/// One line per quality and time interpolation of a sequence experiment.
fn sequence_summary(qualities: &[SequenceQuality]) {
    for q in qualities {
        for m in &q.modes {
            println!(
                "q = {}, {}: {} base image(s), {:.3} s synthesis + {:.3} s loading for {} frames, mean LRMS {:.4}, mean block LRMS {:.4}, mean block p99 {:.4}{}",
                q.quality,
                <&str>::from(m.mode),
                q.baked_images,
                m.synth_s(),
                m.load_s(),
                m.frames.len(),
                m.mean_lrms(),
                m.mean_block_lrms(),
                m.mean_block_p99(),
                mean_flip(&m.frames)
                    .map_or(String::new(), |f| format!(", mean FLIP {f:.4}"))
            );
        }
    }
}

/// Runs one experiment and says where its report is.
pub fn run(experiment: Experiment) -> Result<()> {
    match experiment {
        Experiment::Indirect(args) => {
            let r = indirect::run_indirect(&args.into())?;
            for q in &r.qualities {
                let lrms: f64 =
                    q.frames.iter().map(|f| f.error.lrms).sum::<f64>() / q.frames.len() as f64;
                println!(
                    "q = {}: {} solve(s), {:.3} s in all, mean LRMS {:.4}",
                    q.quality,
                    q.solves.len(),
                    q.total_s(),
                    lrms
                );
            }
            println!("report written to {}", r.out.join("table.md").display());
        }
        Experiment::Views(args) => {
            let r = views::run(&args.into())?;
            for q in &r.qualities {
                let both = |runs: &[views::FillRun]| {
                    runs.iter()
                        .find(|f| f.fill == Fill::Both)
                        .map_or(f64::NAN, |f| f.frame.error.lrms)
                };
                println!(
                    "q = {}: {} views, bases {:.3} apart: LRMS {:.4} (fill both), resampled {:.4}",
                    q.quality,
                    q.plan.views.len(),
                    q.spacing(),
                    both(&q.synthesized),
                    both(&q.resampled)
                );
            }
            println!("report written to {}", r.out.join("table.md").display());
        }
        Experiment::Motion(args) => {
            let r = motion::run(&args.into())?;
            sequence_summary(&r.qualities);
            println!("report written to {}", r.out.join("table.md").display());
        }
        Experiment::Walkthrough(args) => {
            let r = walkthrough::run(&args.into())?;
            sequence_summary(&r.qualities);
            println!("report written to {}", r.out.join("table.md").display());
        }
    }
    Ok(())
}

/// `rangewalk experiment indirect`.
#[derive(clap::Args, Clone, Debug)]
pub struct Indirect {
    pub scene: PathBuf,
    /// Qualities to measure, comma-separated, each in [0, 1].
    #[arg(long, value_delimiter = ',', default_value = "0.3,0.6,0.9")]
    pub quality: Vec<Quality>,
    /// Output folder (written as `<out>.partial`, renamed when complete).
    #[arg(long)]
    pub out: PathBuf,
    /// Frames spread evenly over the animation, both ends included
    /// [default: duration x fps, or 1 for a static scene].
    #[arg(long)]
    pub frames: Option<u32>,
    /// Image size, `<W>x<H>`.
    #[arg(long, default_value = "256x256", value_parser = image::parse_size)]
    pub size: (u32, u32),
    /// Named camera of the scene.
    #[arg(long, default_value = "main")]
    pub camera: String,
    /// Samples per pixel of the path-traced references.
    #[arg(long, default_value_t = 4096)]
    pub reference_spp: u32,
    /// Samples per pixel of the multipass renderer (direct light and
    /// specular rays; indirect light is looked up).
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    #[arg(long, value_parser = choice::<Backend>(), default_value_t = Backend::default_available())]
    pub backend: Backend,
    /// Leave out the FLIP column (when the Python environment of `make deps`
    /// is not installed).
    #[arg(long)]
    pub no_flip: bool,
}

impl From<Indirect> for indirect::IndirectArgs {
    fn from(a: Indirect) -> Self {
        Self {
            scene: a.scene,
            quality: a.quality,
            out: a.out,
            frames: a.frames,
            size: a.size,
            camera: a.camera,
            reference_spp: a.reference_spp,
            spp: a.spp,
            backend: a.backend,
            no_flip: a.no_flip,
        }
    }
}

/// Options every synthesis experiment takes.
#[derive(clap::Args, Clone, Debug)]
pub struct Common {
    pub scene: PathBuf,
    /// Qualities to measure, comma-separated, each in [0, 1]; the same
    /// quality drives every stage (plan, radiosity).
    #[arg(long, value_delimiter = ',', default_value = "0.3,0.6,0.9")]
    pub quality: Vec<Quality>,
    /// Output folder (written as `<out>.partial`, renamed when complete);
    /// the bakes and references in it are reused by a rerun.
    #[arg(long)]
    pub out: PathBuf,
    /// Frame size, `<W>x<H>`.
    #[arg(long, default_value = "256x256", value_parser = image::parse_size)]
    pub size: (u32, u32),
    /// Samples per pixel of the path-traced references.
    #[arg(long, default_value_t = 4096)]
    pub reference_spp: u32,
    /// Samples per pixel of the base images.
    #[arg(long, default_value_t = 16)]
    pub base_spp: u32,
    /// Side of the square full-sphere base images [default: no base pixel
    /// coarser than a frame pixel at the scene's narrowest field of view].
    #[arg(long)]
    pub base_size: Option<u32>,
    /// Subpixels per side each frame pixel is synthesized from (1-4). They
    /// resolve silhouettes down to about a base pixel: with subpixels much
    /// finer than the bases' pixels they add cost, not accuracy.
    #[arg(long, default_value_t = rangewalk::synth::Options::default().supersample)]
    pub supersample: u32,
    /// How the samples of several bases meet in a pixel: `average` where
    /// they agree within the depth tolerance, or `nearest` first (the
    /// paper's order, pinterp's `-q`).
    #[arg(long, value_parser = choice::<Blend>(), default_value_t = rangewalk::synth::Options::default().blend)]
    pub blend: Blend,
    #[arg(long, value_parser = choice::<Backend>(), default_value_t = Backend::default_available())]
    pub backend: Backend,
    /// What the planner's view-space cells must reach `--quality` in.
    #[arg(long, value_parser = choice::<ViewFitness>(), default_value_t = ViewFitness::Ids)]
    pub view_fitness: ViewFitness,
    /// Where the bases' diffuse indirect light comes from (as `bake
    /// --indirect`).
    #[arg(long, value_parser = choice::<IndirectSource>(), default_value_t = IndirectSource::Radiosity)]
    pub indirect: IndirectSource,
    /// Leave out the FLIP column (when the Python environment of `make deps`
    /// is not installed).
    #[arg(long)]
    pub no_flip: bool,
}

impl From<Common> for CommonArgs {
    fn from(a: Common) -> Self {
        Self {
            scene: a.scene,
            quality: a.quality,
            out: a.out,
            size: a.size,
            reference_spp: a.reference_spp,
            base_spp: a.base_spp,
            base_size: a.base_size,
            supersample: a.supersample,
            blend: a.blend,
            backend: a.backend,
            view_fitness: a.view_fitness,
            indirect: a.indirect,
            no_flip: a.no_flip,
        }
    }
}

/// Options of the experiments over a sequence of frames.
#[derive(clap::Args, Clone, Debug)]
pub struct Sequence {
    /// Frames spread evenly over the animation (`motion`) or the walk path
    /// (`walkthrough`), both ends included [default: every frame at the
    /// scene's rate, both ends included: 31 for one second at 30 frames/s].
    #[arg(long)]
    pub frames: Option<u32>,
    /// Time interpolations to compare.
    #[arg(
        long,
        value_parser = choice::<TimeInterp>(),
        value_delimiter = ',',
        default_value = "linear,motion,reshade"
    )]
    pub time_interp: Vec<TimeInterp>,
    /// Hole filling.
    #[arg(long, value_parser = choice::<Fill>(), default_value_t = Fill::Both)]
    pub fill: Fill,
}

impl From<Sequence> for SequenceArgs {
    fn from(a: Sequence) -> Self {
        Self {
            frames: a.frames,
            time_interp: a.time_interp,
            fill: a.fill,
        }
    }
}

/// What `rangewalk experiment views` takes.
#[derive(clap::Args, Clone, Debug)]
pub struct Views {
    #[command(flatten)]
    pub common: Common,
    /// Named camera whose view direction and field of view the target view
    /// takes.
    #[arg(long, default_value = "main")]
    pub camera: String,
    /// The 1D view subspace, `x,y,z:x,y,z` [default: the scene's segment,
    /// or the line through the middle of its rectangle or box along the
    /// longest side].
    #[arg(long, value_parser = rangewalk::scene::parse_segment, allow_hyphen_values = true)]
    pub view_segment: Option<ViewSpace>,
    /// Put the target view at this fraction of the segment for every
    /// quality [default: for each quality, midway between the two adjacent
    /// bases whose middle is nearest the segment's].
    #[arg(long)]
    pub target: Option<f32>,
}

impl From<Views> for views::ViewsArgs {
    fn from(a: Views) -> Self {
        Self {
            common: a.common.into(),
            camera: a.camera,
            view_segment: a.view_segment,
            target: a.target,
        }
    }
}

/// What `rangewalk experiment motion` takes.
#[derive(clap::Args, Clone, Debug)]
pub struct Motion {
    #[command(flatten)]
    pub common: Common,
    /// The fixed view: a named camera of the scene. Its position is the one
    /// base view.
    #[arg(long, default_value = "main")]
    pub camera: String,
    #[command(flatten)]
    pub sequence: Sequence,
}

impl From<Motion> for motion::MotionArgs {
    fn from(a: Motion) -> Self {
        Self {
            common: a.common.into(),
            camera: a.camera,
            sequence: a.sequence.into(),
        }
    }
}

/// What `rangewalk experiment walkthrough` takes.
#[derive(clap::Args, Clone, Debug)]
pub struct Walkthrough {
    #[command(flatten)]
    pub common: Common,
    /// Walk path of the scene.
    #[arg(long, default_value = "walk")]
    pub path: String,
    #[command(flatten)]
    pub sequence: Sequence,
    /// Base views each frame is made from, nearest first.
    #[arg(long, default_value_t = 4)]
    pub bases: usize,
    /// Which planned views to bake.
    #[arg(long, value_parser = choice::<BakeViews>(), default_value_t = BakeViews::All)]
    pub bake_views: BakeViews,
    /// Length of the walk-through (frames) the bake is amortized over in
    /// the summary's speed-up.
    #[arg(long, default_value_t = 300)]
    pub amortize_frames: u64,
}

impl From<Walkthrough> for walkthrough::WalkthroughArgs {
    fn from(a: Walkthrough) -> Self {
        Self {
            common: a.common.into(),
            path: a.path,
            sequence: a.sequence.into(),
            bases: a.bases,
            bake_views: a.bake_views,
            amortize_frames: a.amortize_frames,
        }
    }
}
