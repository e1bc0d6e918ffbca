//! `rangewalk experiment indirect`: indirect illumination from radiosity
//! records against converged path tracing, per quality, over an animation
//! (the paper's Tables 1 and 2, §5.1).
//!
//! For each quality the whole object-space pipeline runs once —
//! simplification, temporal decomposition with its radiosity solves — and
//! then every frame is interpolated and rendered by the multipass renderer.
//! Each frame is compared with a path-traced reference; the path tracer is
//! also measured at increasing sample counts (its convergence curve) and at
//! the sample count that costs what the radiosity method costs, which is the
//! comparison that decides whether the method pays.

pub mod report;

use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{ensure, Context, Result};
use glam::Vec3;

use crate::accel::{self, Backend, InstancedEngine};
use crate::camera::Camera;
use crate::eval::experiments::common::convergence::{
    convergence, seconds_per_sample, ConvergencePoint, Target, TEST_SEED,
};
use crate::eval::experiments::common::staging::{Staging, REFERENCE_DIR};
use crate::eval::experiments::common::synthesize::flip_means;
use crate::eval::flip::Flip;
use crate::eval::metrics::{self, ImageError, Pixels};
use crate::eval::reference::{self, Reference};
use crate::quality::Quality;
use crate::radiosity::lookup::IrradianceCache;
use crate::radiosity::{self, temporal, SimplifyStats, SolveStats};
use crate::render::{multipass, RenderSettings};
use crate::scene::Scene;

/// What `rangewalk experiment indirect` takes.
#[derive(Clone, Debug)]
pub struct IndirectArgs {
    pub scene: PathBuf,
    /// Qualities to measure, comma-separated.
    pub quality: Vec<Quality>,
    /// Output folder (written as `<out>.partial`, renamed when complete).
    pub out: PathBuf,
    /// Frames spread evenly over the animation, both ends included
    /// [default: duration x fps, or 1 for a static scene].
    pub frames: Option<u32>,
    /// Image size, `<W>x<H>`.
    pub size: (u32, u32),
    /// Named camera of the scene.
    pub camera: String,
    /// Samples per pixel of the path-traced references.
    pub reference_spp: u32,
    /// Samples per pixel of the multipass renderer (direct light and
    /// specular rays; indirect light is looked up).
    pub spp: u32,
    pub backend: Backend,
    /// Leave out the FLIP column (when the Python environment of `make deps`
    /// is not installed).
    pub no_flip: bool,
}

/// One rendered frame compared with its reference.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameResult {
    pub frame: usize,
    /// Scene time (s).
    pub time: f32,
    /// Interpolating the records in time and building their cache.
    pub interpolation_s: f64,
    pub render_s: f64,
    pub error: ImageError,
    pub flip: Option<f64>,
}

/// Everything measured for one quality.
#[derive(Clone, Debug)]
pub struct QualityRun {
    pub quality: f32,
    pub simplify: SimplifyStats,
    /// Wall time of simplification.
    pub simplify_s: f64,
    /// Wall time of the temporal decomposition, solves included.
    pub decompose_s: f64,
    pub records: usize,
    /// The solve times chosen by the decomposition and what each cost.
    pub solves: Vec<(f32, SolveStats)>,
    pub frames: Vec<FrameResult>,
    /// Radiance of the preview frame.
    pub preview: Vec<Vec3>,
}

impl QualityRun {
    /// Radiosity solves: the paper's "indirect generation".
    pub fn indirect_generation_s(&self) -> f64 {
        self.solves.iter().map(|(_, s)| s.seconds).sum()
    }

    /// Simplification and the decomposition's own work (choosing the
    /// times, comparing solutions): the paper's "scene decomposition".
    pub fn scene_decomposition_s(&self) -> f64 {
        self.simplify_s + (self.decompose_s - self.indirect_generation_s()).max(0.0)
    }

    pub fn interpolation_s(&self) -> f64 {
        self.frames.iter().map(|f| f.interpolation_s).sum()
    }

    pub fn render_s(&self) -> f64 {
        self.frames.iter().map(|f| f.render_s).sum()
    }

    pub fn total_s(&self) -> f64 {
        self.simplify_s + self.decompose_s + self.interpolation_s() + self.render_s()
    }
}

/// The path tracer at one sample count over every frame.
#[derive(Clone, Debug)]
pub struct PathTracerRun {
    pub spp: u32,
    /// The quality whose total time this run matches.
    pub matches: Vec<f32>,
    /// Whether the sample count was capped below the time match (at a
    /// quarter of the reference's, beyond which the reference's own noise
    /// dominates the error).
    pub capped: bool,
    pub frames: Vec<FrameResult>,
    pub preview: Vec<Vec3>,
}

impl PathTracerRun {
    pub fn total_s(&self) -> f64 {
        self.frames.iter().map(|f| f.render_s).sum()
    }
}

/// The whole experiment's measurements.
#[derive(Clone, Debug)]
pub struct IndirectResults {
    pub args: IndirectArgs,
    pub times: Vec<f32>,
    pub preview_frame: usize,
    pub references: Vec<Reference>,
    pub qualities: Vec<QualityRun>,
    pub convergence: Vec<ConvergencePoint>,
    pub equal_time: Vec<PathTracerRun>,
    /// Stages left out, and why.
    pub notes: Vec<String>,
    /// Where the results were written.
    pub out: PathBuf,
}

/// Runs the experiment and writes its report to `args.out`.
pub fn run_indirect(args: &IndirectArgs) -> Result<IndirectResults> {
    crate::image::check_output_dir("--out", &args.out)?;
    ensure!(!args.quality.is_empty(), "--quality names no quality");
    let qualities = args.quality.clone();
    ensure!(args.spp > 0, "--spp must be at least 1");
    ensure!(args.reference_spp > 0, "--reference-spp must be at least 1");
    ensure!(args.frames != Some(0), "--frames must be at least 1");
    let scene = Scene::load(&args.scene)?;
    let (w, h) = args.size;
    let camera = scene.camera(&args.camera)?.perspective(w, h)?;
    let times = frame_times(&scene, args.frames);
    let preview_frame = times.len() / 2;
    let mut notes = Vec::new();
    if scene.dropped_triangles > 0 {
        notes.push(format!(
            "{} zero-area triangle(s) dropped while loading the scene",
            scene.dropped_triangles
        ));
    }
    notes.extend(scene.warnings.iter().cloned());
    if scene.is_static() {
        notes.push(
            "static scene: one time sample, no temporal decomposition (one radiosity \
             solve, nothing interpolated in time)"
                .to_string(),
        );
    }
    if !scene.has_specular() {
        notes.push("no glossy or mirror surfaces: no specular rays are traced".to_string());
    }
    let flip = if args.no_flip {
        notes.push("FLIP left out (--no-flip)".to_string());
        None
    } else {
        Some(Flip::locate().context("FLIP is part of the report; pass --no-flip to leave it out")?)
    };

    let staging = Staging::begin(&args.out)?;
    let mut engine = accel::build(args.backend, &scene.geometry(), &scene.at(times[0]))
        .with_context(|| format!("building the {} ray engine", args.backend))?;
    let references = reference::references(
        &scene,
        engine.as_mut(),
        &camera,
        &args.camera,
        &times,
        args.reference_spp,
        &staging.dir().join(REFERENCE_DIR),
    )?;
    notes.extend(reference::reuse_note(&references));
    let refs: Vec<&[Vec3]> = references.iter().map(|r| r.radiance.as_slice()).collect();
    let ctx = Frames {
        scene: &scene,
        camera: &camera,
        times: &times,
        refs: &refs,
        flip: flip.as_ref(),
        preview_frame,
    };

    let mut runs = Vec::new();
    for &q in &qualities {
        runs.push(
            run_quality(&ctx, engine.as_mut(), q, args.spp)
                .with_context(|| format!("quality {}", q.get()))?,
        );
    }

    // Equal time: each quality's cost per frame, converted to samples per
    // pixel with the path tracer's measured cost per sample.
    let budgets: Vec<f64> = runs
        .iter()
        .map(|r| r.total_s() / times.len() as f64)
        .collect();
    let max_spp = (args.reference_spp / 4).max(1);
    let target = Target {
        max_spp,
        seconds: budgets.iter().copied().fold(0.0, f64::max),
        lrms: runs
            .iter()
            .map(|r| r.frames[preview_frame].error.lrms)
            .fold(f64::INFINITY, f64::min),
        flip: runs
            .iter()
            .filter_map(|r| r.frames[preview_frame].flip)
            .reduce(f64::min),
    };
    let convergence = convergence(
        &scene,
        engine.as_mut(),
        &camera,
        times[preview_frame],
        refs[preview_frame],
        target,
        flip.as_ref(),
    )?;
    let mut equal_time: Vec<PathTracerRun> = Vec::new();
    let mut by_spp: HashMap<u32, usize> = HashMap::new();
    for (run, &budget) in runs.iter().zip(&budgets) {
        let (spp, capped) = equal_time_spp(&convergence, budget, max_spp);
        if let Some(&i) = by_spp.get(&spp) {
            equal_time[i].matches.push(run.quality);
            continue;
        }
        eprintln!(
            "path tracer at {spp} spp ({:.3} s per frame, as quality {}):",
            budget, run.quality
        );
        let mut pt = path_tracer_run(&ctx, engine.as_mut(), spp)?;
        pt.matches.push(run.quality);
        pt.capped = capped;
        by_spp.insert(spp, equal_time.len());
        equal_time.push(pt);
    }

    let mut results = IndirectResults {
        args: args.clone(),
        times,
        preview_frame,
        references,
        qualities: runs,
        convergence,
        equal_time,
        notes,
        out: args.out.clone(),
    };
    report::write(staging.dir(), &results)?;
    results.out = staging.finish()?;
    Ok(results)
}

/// Frame times spread evenly over the animation, both ends included.
pub fn frame_times(scene: &Scene, frames: Option<u32>) -> Vec<f32> {
    let a = scene.animation;
    let n = frames.unwrap_or_else(|| {
        if scene.is_static() {
            1
        } else {
            ((a.end - a.start) * a.fps).round().max(1.0) as u32
        }
    });
    super::common::setup::spread(a.start, a.end, n)
}

/// What every per-frame loop needs.
struct Frames<'a> {
    scene: &'a Scene,
    camera: &'a Camera,
    times: &'a [f32],
    refs: &'a [&'a [Vec3]],
    flip: Option<&'a Flip>,
    preview_frame: usize,
}

impl Frames<'_> {
    /// FLIP of each frame against its reference, in one batch.
    fn flip(&self, images: &[Vec<Vec3>]) -> Result<Vec<Option<f64>>> {
        flip_means(self.flip, self.camera, self.refs, images)
    }
}

fn run_quality(
    ctx: &Frames,
    engine: &mut dyn InstancedEngine,
    q: Quality,
    spp: u32,
) -> Result<QualityRun> {
    let tag = format!("q = {}", q.get());
    eprintln!("{tag}: simplifying");
    let start = Instant::now();
    let simplified = radiosity::simplify(ctx.scene, engine, q)?;
    let simplify_s = start.elapsed().as_secs_f64();
    let s = &simplified.stats;
    eprintln!(
        "{tag}: {} surfaces, {} pruned, {} patches, {} records ({simplify_s:.3} s); decomposing in time",
        s.initial_surfaces,
        s.pruned_surfaces,
        s.final_surfaces,
        simplified.records.len()
    );
    let start = Instant::now();
    let series = temporal::decompose(ctx.scene, &simplified, engine, q)?;
    let decompose_s = start.elapsed().as_secs_f64();
    eprintln!(
        "{tag}: {} solve(s) at t = {:?} ({decompose_s:.3} s)",
        series.solutions.len(),
        series.times
    );
    let settings = RenderSettings {
        spp,
        max_depth: None,
        seed: TEST_SEED,
    };
    let mut frames = Vec::with_capacity(ctx.times.len());
    let mut images = Vec::with_capacity(ctx.times.len());
    for (i, &t) in ctx.times.iter().enumerate() {
        let start = Instant::now();
        let indirect = series.indirect_at(t);
        let cache = IrradianceCache::new(&simplified, &indirect)?;
        let interpolation_s = start.elapsed().as_secs_f64();
        let start = Instant::now();
        engine.set_transforms(&ctx.scene.at(t))?;
        let (img, _) = multipass::render(ctx.scene, &*engine, ctx.camera, t, &settings, &cache)?;
        let render_s = start.elapsed().as_secs_f64();
        let error = metrics::compare(&img, Pixels::of(ctx.camera, ctx.refs[i]), None)
            .with_context(|| format!("frame {i} (t = {t} s)"))?;
        eprintln!(
            "{tag}: frame {}/{} t = {t:.4} s: LRMS {:.4}, bias {:+.4} ({render_s:.3} s)",
            i + 1,
            ctx.times.len(),
            error.lrms,
            error.bias
        );
        frames.push(FrameResult {
            frame: i,
            time: t,
            interpolation_s,
            render_s,
            error,
            flip: None,
        });
        images.push(img.radiance);
    }
    for (f, v) in frames.iter_mut().zip(ctx.flip(&images)?) {
        f.flip = v;
    }
    Ok(QualityRun {
        quality: q.get(),
        simplify: simplified.stats,
        simplify_s,
        decompose_s,
        records: simplified.records.len(),
        solves: series
            .times
            .iter()
            .zip(&series.solutions)
            .map(|(&t, s)| (t, s.stats))
            .collect(),
        frames,
        preview: images.swap_remove(ctx.preview_frame),
    })
}

fn path_tracer_run(
    ctx: &Frames,
    engine: &mut dyn InstancedEngine,
    spp: u32,
) -> Result<PathTracerRun> {
    let mut frames = Vec::with_capacity(ctx.times.len());
    let mut images = Vec::with_capacity(ctx.times.len());
    for (i, &t) in ctx.times.iter().enumerate() {
        let (radiance, render_s) =
            reference::path_trace(ctx.scene, engine, ctx.camera, t, spp, TEST_SEED)?;
        let error = metrics::compare(
            Pixels::of(ctx.camera, &radiance),
            Pixels::of(ctx.camera, ctx.refs[i]),
            None,
        )
        .with_context(|| format!("path tracer, frame {i} (t = {t} s)"))?;
        eprintln!(
            "path tracer {spp} spp: frame {}/{}: LRMS {:.4} ({render_s:.3} s)",
            i + 1,
            ctx.times.len(),
            error.lrms
        );
        frames.push(FrameResult {
            frame: i,
            time: t,
            interpolation_s: 0.0,
            render_s,
            error,
            flip: None,
        });
        images.push(radiance);
    }
    for (f, v) in frames.iter_mut().zip(ctx.flip(&images)?) {
        f.flip = v;
    }
    Ok(PathTracerRun {
        spp,
        matches: Vec::new(),
        capped: false,
        frames,
        preview: images.swap_remove(ctx.preview_frame),
    })
}

/// Samples per pixel that take `budget` seconds, from the cost per sample
/// of the largest measured render (small ones are dominated by fixed
/// costs); at least 1 and at most `max_spp` (`true` when capped there).
fn equal_time_spp(curve: &[ConvergencePoint], budget: f64, max_spp: u32) -> (u32, bool) {
    let Some(per_sample) = seconds_per_sample(curve) else {
        return (1, false);
    };
    let spp = if per_sample > 0.0 {
        (budget / per_sample).round()
    } else {
        f64::INFINITY
    };
    if spp > max_spp as f64 {
        (max_spp, true)
    } else {
        (spp.max(1.0) as u32, false)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(spp: u32, seconds: f64) -> ConvergencePoint {
        ConvergencePoint {
            spp,
            seconds,
            error: ImageError {
                lrms: 1.0 / (spp as f64).sqrt(),
                bias: 0.0,
                block_lrms: 0.5 / (spp as f64).sqrt(),
                block_p99: 1.0 / (spp as f64).sqrt(),
                pixels: 1,
            },
            flip: None,
        }
    }

    #[test]
    fn equal_time_uses_the_cost_per_sample_of_the_largest_render() {
        let curve = [point(1, 0.5), point(2, 0.6), point(4, 0.8)];
        assert_eq!(equal_time_spp(&curve, 2.0, 64), (10, false));
        assert_eq!(equal_time_spp(&curve, 0.01, 64), (1, false));
        assert_eq!(equal_time_spp(&curve, 100.0, 64), (64, true));
    }

    #[test]
    fn frames_cover_the_animation() {
        let mut scene = Scene::load(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/cornell-box/scene.toml"
        ))
        .unwrap();
        let t = frame_times(&scene, None);
        assert_eq!(t.len(), 30);
        assert_eq!((t[0], t[29]), (0.0, 1.0));
        assert_eq!(frame_times(&scene, Some(3)), [0.0, 0.5, 1.0]);
        assert_eq!(frame_times(&scene, Some(1)), [0.0]);
        for o in &mut scene.objects {
            o.motion = crate::scene::Motion::new(Vec::new());
        }
        scene.animation.end = 0.0;
        assert_eq!(frame_times(&scene, None), [0.0]);
    }

    #[test]
    fn sizes_parse() {
        assert_eq!(crate::image::parse_size("32x16"), Ok((32, 16)));
        assert!(crate::image::parse_size("0x16").is_err());
        assert!(crate::image::parse_size("32").is_err());
    }
}
