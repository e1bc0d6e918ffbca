//! The `synth` and `walk` commands.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use rangewalk::bake::Bake;
use rangewalk::eval::flip::Flip;
use rangewalk::eval::walkcheck::ReferenceChecks;
use rangewalk::image;
use rangewalk::scene::Scene;
use rangewalk::synth::walk::{self, WalkSettings};
use rangewalk::synth::{
    self, view_space_warning, Blend, Fill, Filter, Options, Synthesizer, TimeInterp, DEFAULT_BUDGET,
};

use super::{choice, flag};

/// Frame size of `rangewalk synth` and `walk`.
pub const DEFAULT_SIZE: &str = "512x512";

/// How frames are made from the bases (shared by `synth` and `walk`).
#[derive(clap::Args, Clone, Debug)]
pub struct SynthOptions {
    /// The scene the bake was made from [default: the one its manifest
    /// names].
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Hole filling (pinterp's -f0, -ff, -fb, -fa).
    #[arg(long, value_parser = choice::<Fill>(), default_value_t = Options::default().fill)]
    pub fill: Fill,
    /// Interpolation between base times.
    #[arg(long, value_parser = choice::<TimeInterp>(), default_value_t = Options::default().time_interp)]
    pub time_interp: TimeInterp,
    /// Base views to project, nearest first.
    #[arg(long, default_value_t = Options::default().bases)]
    pub bases: usize,
    /// Samples within the depth tolerance: averaged by ray angle, or the
    /// nearest base's.
    #[arg(long, value_parser = choice::<Blend>(), default_value_t = Options::default().blend)]
    pub blend: Blend,
    /// Relative depth tolerance of the z-buffer.
    #[arg(long, default_value_t = Options::default().tolerance)]
    pub tolerance: f32,
    /// Farthest a background fill carries a value, in pixels.
    #[arg(long, default_value_t = Options::default().fill_reach)]
    pub fill_reach: u16,
    /// Light samples per pixel when re-shading.
    #[arg(long, default_value_t = Options::default().reshade_samples)]
    pub reshade_samples: u32,
    /// Rays per side of a pixel at or beside a light or a silhouette
    /// against the sky, traced to find what fraction of it each surface
    /// covers; 0 keeps lights and silhouettes as reprojected.
    #[arg(long, default_value_t = Options::default().light_rays)]
    pub light_rays: u32,
    #[arg(long, default_value_t = Options::default().seed)]
    pub seed: u64,
    /// Subpixels per side each frame pixel is synthesized from (1: none),
    /// so that pixels a silhouette crosses show each surface by its share
    /// (with --fill foreground or both, whose splats cover subpixels).
    #[arg(long, default_value_t = Options::default().supersample,
          value_parser = clap::value_parser!(u32).range(1..=synth::MAX_SUPERSAMPLE as i64))]
    pub supersample: u32,
    /// Which frame pixels a splat reaches: every one it overlaps, weighed
    /// by the overlap (box), or only those whose centres it covers (cover:
    /// a quarter to a third faster, LRMS up to a tenth higher from bases
    /// as fine as the frame, up to a third from coarser ones).
    #[arg(long, value_parser = choice::<Filter>(), default_value_t = Options::default().filter)]
    pub filter: Filter,
    /// Memory for bases held between frames, in MiB.
    #[arg(long, default_value_t = DEFAULT_BUDGET >> 20)]
    pub base_memory: usize,
    /// Exposure of previews in stops.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
}

impl SynthOptions {
    /// The synthesis options, checked against the library's limits (named
    /// by their flags), and that frames of `size` stay within them.
    pub fn options(&self, size: (u32, u32)) -> Result<Options> {
        let options = Options {
            fill: self.fill,
            time_interp: self.time_interp,
            bases: self.bases,
            blend: self.blend,
            tolerance: self.tolerance,
            fill_reach: self.fill_reach,
            reshade_samples: self.reshade_samples,
            light_rays: self.light_rays,
            seed: self.seed,
            supersample: self.supersample,
            filter: self.filter,
        };
        options.validate(size, &flag)?;
        Ok(options)
    }

    /// `--base-memory` in bytes.
    pub fn base_memory_bytes(&self) -> Result<usize> {
        self.base_memory.checked_mul(1 << 20).with_context(|| {
            format!(
                "--base-memory {} MiB overflows a byte count; give at most {} MiB",
                self.base_memory,
                usize::MAX >> 20
            )
        })
    }

    /// The bake in `dir` and the scene it was made from, checked against
    /// each other.
    pub fn open(&self, dir: &Path) -> Result<(Scene, Bake)> {
        synth::open(dir, self.scene.as_deref())
    }
}

#[derive(clap::Args, Clone, Debug)]
pub struct SynthArgs {
    /// A complete bake directory (`rangewalk bake`).
    pub bake: PathBuf,
    /// Named camera of the scene.
    #[arg(long, default_value = "main")]
    pub camera: String,
    /// The camera of this walk path at --time instead of a named camera
    /// (the frame `rangewalk walk` and `rangewalk view --path` show then).
    #[arg(long, conflicts_with = "camera")]
    pub path: Option<String>,
    /// Scene time in seconds (within the animation of an animated scene,
    /// within the path's keys with --path).
    #[arg(long, allow_negative_numbers = true)]
    pub time: f32,
    #[arg(long, default_value = DEFAULT_SIZE, value_parser = image::parse_size)]
    pub size: (u32, u32),
    /// Output range image (OpenEXR).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write a tone-mapped PNG here.
    #[arg(long)]
    pub preview: Option<PathBuf>,
    #[command(flatten)]
    pub synth: SynthOptions,
}

pub fn synth(args: &SynthArgs) -> Result<()> {
    let options = args.synth.options(args.size)?;
    let budget = args.synth.base_memory_bytes()?;
    image::check_output("--out", &args.out, image::OutputKind::Exr)?;
    if let Some(p) = &args.preview {
        image::check_output("--preview", p, image::OutputKind::Png)?;
    }
    let (scene, bake) = args.synth.open(&args.bake)?;
    scene.check_time(args.time).context("--time")?;
    let desc = match &args.path {
        Some(p) => {
            let path = scene.path(p)?;
            let (first, last) = path.span();
            anyhow::ensure!(
                (first..=last).contains(&args.time),
                "--time {} lies outside path `{p}`'s keys, [{first}, {last}] s, where its camera would stand still: give a time in that range",
                args.time
            );
            path.at(args.time)
        }
        None => scene.camera(&args.camera)?.clone(),
    };
    if let Some(w) = view_space_warning(&scene, &format!("camera `{}`", desc.name), desc.position) {
        eprintln!("{w}");
    }
    let camera = desc.perspective(args.size.0, args.size.1)?;
    let mut synth = Synthesizer::new(&scene, &bake, budget);
    let (frame, stats) = synth.frame(&camera, args.time, &options)?;
    image::write_exr(&args.out, &frame)?;
    if let Some(p) = &args.preview {
        image::write_png_preview(
            p,
            frame.width,
            frame.height,
            &frame.radiance,
            args.synth.exposure,
        )?;
    }
    let mut extra = String::new();
    if stats.plan.reshade && !stats.plan.direct {
        extra += ", light not drawn again (the frame is at its bases' times, or nothing in the scene moves)";
    } else if stats.plan.reshade {
        extra += &format!(
            ", {} pixel(s) whose light changed since the base times re-shaded with {} light samples, \
             diffuse indirect light {}, {} mirror pixel(s) no base showed",
            stats.reshaded,
            options.reshade_samples,
            if stats.indirect_corrected {
                "corrected by the radiosity records"
            } else {
                "as the bases hold it (no radiosity records, or a static scene)"
            },
            stats.mirror_misses
        );
    }
    if options.blend == Blend::Nearest {
        extra += &format!(
            ", {} base pixel(s) left out where nearer bases decided",
            stats.hidden
        );
    }
    println!(
        "{}: {}x{} at t = {} s from {} base image(s) ({}): {:.1} ms synthesis + {:.3} s reading bases; {} hole pixel(s), {} filled, {} open to the sky, {} pixel(s) at lights and silhouettes against the sky traced{}",
        args.out.display(),
        frame.width,
        frame.height,
        args.time,
        stats.images.len(),
        stats
            .images
            .iter()
            .map(|&k| bake.manifest.images[k].file.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        1e3 * (stats.seconds - stats.load_seconds),
        stats.load_seconds,
        stats.holes,
        stats.filled,
        stats.sky,
        stats.light_pixels,
        extra
    );
    Ok(())
}

#[derive(clap::Args, Clone, Debug)]
pub struct WalkArgs {
    /// A complete bake directory (`rangewalk bake`).
    pub bake: PathBuf,
    /// Walk path of the scene.
    #[arg(long)]
    pub path: String,
    #[arg(long, default_value = DEFAULT_SIZE, value_parser = image::parse_size)]
    pub size: (u32, u32),
    /// Output folder: frames (EXR and PNG), walk.png (animated), summary.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Frames per second of scene time [default: the scene's].
    #[arg(long)]
    pub fps: Option<f32>,
    /// Path-trace every n-th frame (and the last) too: their LRMS, bias,
    /// 8x8-block LRMS and 99th percentile, and FLIP go in the summary;
    /// contact.png shows each synthesized above its reference above FLIP's
    /// error map.
    #[arg(long)]
    pub check_every: Option<usize>,
    /// Samples per pixel of those reference frames.
    #[arg(long, default_value_t = 256)]
    pub check_spp: u32,
    /// Leave FLIP out of the check (when the Python environment of `make
    /// deps` is not installed).
    #[arg(long, requires = "check_every")]
    pub no_flip: bool,
    #[command(flatten)]
    pub synth: SynthOptions,
}

pub fn walk(args: &WalkArgs) -> Result<()> {
    let options = args.synth.options(args.size)?;
    let budget = args.synth.base_memory_bytes()?;
    image::check_output_dir("--out", &args.out)?;
    rangewalk::output::check_only(&args.out, &walk::CONTENTS)?;
    let (scene, bake) = args.synth.open(&args.bake)?;
    let mut synth = Synthesizer::new(&scene, &bake, budget);
    let settings = WalkSettings {
        path: args.path.clone(),
        width: args.size.0,
        height: args.size.1,
        fps: args.fps,
        options,
        exposure: args.synth.exposure,
    };
    let mut checks = match args.check_every {
        None => None,
        Some(every) => {
            let flip = if args.no_flip {
                None
            } else {
                Some(Flip::locate().context(
                    "--check-every measures FLIP against the references; pass --no-flip to leave it out",
                )?)
            };
            Some(ReferenceChecks::new(
                every,
                args.check_spp,
                options.seed,
                flip,
            )?)
        }
    };
    let s = walk::walk(
        &mut synth,
        &settings,
        &args.out,
        checks.as_mut().map(|c| c as &mut dyn walk::FrameChecker),
    )?;
    let holes: usize = s.holes.iter().sum();
    println!(
        "{}: {} frames of path `{}` at {}x{}: {:.1} frames/s synthesis ({:.3} s), {:.3} s reading {} base image(s), {:.3} s in all; {} hole pixel(s); peak memory {}; {} bytes per base pixel",
        s.out.display(),
        s.frames,
        s.path,
        args.size.0,
        args.size.1,
        s.frames_per_second,
        s.synthesis_seconds,
        s.load_seconds,
        s.base_loads,
        s.total_seconds,
        holes,
        s.peak_resident_bytes
            .map_or("unknown".to_string(), |b| format!("{:.0} MiB", b as f64 / (1 << 20) as f64)),
        s.bytes_per_base_pixel
    );
    if !s.checks.is_empty() {
        println!("{}", check_line(&s.checks, args.check_spp, &s.out));
    }
    Ok(())
}

/// The line that sums up a walk's checks: the mean of each error over the
/// checked frames, and what contact.png shows, row by row.
fn check_line(checks: &[walk::FrameCheck], spp: u32, out: &Path) -> String {
    let mean =
        |f: fn(&walk::FrameCheck) -> f64| checks.iter().map(f).sum::<f64>() / checks.len() as f64;
    let seconds: f64 = checks.iter().map(|c| c.reference_seconds).sum();
    let flips: Option<Vec<f64>> = checks.iter().map(|c| c.flip).collect();
    let (flip, rows) = match flips {
        Some(v) => (
            format!(", mean FLIP {:.4}", v.iter().sum::<f64>() / v.len() as f64),
            "synthesized (top row), path-traced (middle) and FLIP's error map (bottom: black \
             for no visible difference, through purple and orange to pale yellow at FLIP 1)",
        ),
        None => (
            "; FLIP left out (--no-flip)".to_string(),
            "synthesized (top row) above path-traced",
        ),
    };
    format!(
        "checked {} frame(s) against {spp}-spp path-traced references ({seconds:.3} s to render): \
         mean LRMS {:.4}, mean bias {:+.1}%, mean 8x8-block LRMS {:.4}, mean block p99 {:.4}{flip}; \
         {} shows them: {rows}",
        checks.len(),
        mean(|c| c.lrms),
        100.0 * mean(|c| c.bias),
        mean(|c| c.block_lrms),
        mean(|c| c.block_p99),
        out.join("contact.png").display()
    )
}
