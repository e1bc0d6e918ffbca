//! What the synthesis experiments (`views`, `motion`, `walkthrough`: the
//! paper's Tables 3-5) share before synthesis: their common options, and
//! plans, bakes and references cached in the output folder.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, ensure, Context, Result};
use serde::{Deserialize, Serialize};

use crate::accel::{self, Backend, InstancedEngine};
use crate::bake::{self, Bake, BaseProjection, IndirectSource, Manifest, Shard};
use crate::camera::Camera;
use crate::eval::flip::Flip;
use crate::eval::reference::{self, Reference};
use crate::plan::{self, Plan, PlanOptions, ViewFitness};
use crate::quality::Quality;
use crate::scene::hash::ContentHash;
use crate::scene::Scene;
use crate::synth::{self, Blend, Fill, TimeInterp};

/// Seed of the base images: `rangewalk bake`'s default (each image's
/// sampler is seeded from it, the view and the time).
const BAKE_SEED: u64 = 0;

/// Where a bake's run times are kept beside its images, so that a rerun
/// that reuses the bake still reports what it cost.
const TIMING_FILE: &str = "experiment-timing.json";

/// Options every synthesis experiment takes.
#[derive(Clone, Debug)]
pub struct CommonArgs {
    pub scene: PathBuf,
    /// Qualities to measure, comma-separated, each in [0, 1]; the same
    /// quality drives every stage (plan, radiosity).
    pub quality: Vec<Quality>,
    /// Output folder (written as `<out>.partial`, renamed when complete);
    /// the bakes and references in it are reused by a rerun.
    pub out: PathBuf,
    /// Frame size, `<W>x<H>`.
    pub size: (u32, u32),
    /// Samples per pixel of the path-traced references.
    pub reference_spp: u32,
    /// Samples per pixel of the base images.
    pub base_spp: u32,
    /// Side of the square full-sphere base images [default: no base pixel
    /// coarser than a frame pixel at the scene's narrowest field of view].
    pub base_size: Option<u32>,
    /// Subpixels per side of every synthesized frame pixel.
    pub supersample: u32,
    /// How the samples of several bases meet in a pixel.
    pub blend: Blend,
    pub backend: Backend,
    /// What the planner's view-space cells must reach the quality in.
    pub view_fitness: ViewFitness,
    /// Where the bases' diffuse indirect light comes from.
    pub indirect: IndirectSource,
    /// Leave out the FLIP column (when the Python environment of `make deps`
    /// is not installed).
    pub no_flip: bool,
}

/// Options of the experiments over a sequence of frames.
#[derive(Clone, Debug)]
pub struct SequenceArgs {
    /// Frames spread evenly over the animation (`motion`) or the walk path
    /// (`walkthrough`), both ends included [default: every frame at the
    /// scene's rate, both ends included: 31 for one second at 30 frames/s].
    pub frames: Option<u32>,
    /// Time interpolations to compare.
    pub time_interp: Vec<TimeInterp>,
    /// Hole filling.
    pub fill: Fill,
}

impl SequenceArgs {
    /// Frame times over `span` at `fps`, or `--frames` spread evenly.
    pub fn times(&self, span: (f32, f32), fps: f32) -> Result<Vec<f32>> {
        ensure!(!self.time_interp.is_empty(), "--time-interp names no mode");
        match self.frames {
            Some(0) => bail!("--frames must be at least 1"),
            Some(n) => Ok(spread(span.0, span.1, n)),
            None => {
                ensure!(
                    fps.is_finite() && fps > 0.0,
                    "the scene's frame rate {fps} is not positive"
                );
                Ok(synth::walk::frame_times(span, fps))
            }
        }
    }
}

/// The checked options and what they name.
pub struct Setup {
    pub scene: Scene,
    pub qualities: Vec<Quality>,
    pub flip: Option<Flip>,
    /// Side of the base images.
    pub base_size: u32,
    pub notes: Vec<String>,
}

impl CommonArgs {
    /// Checks the options, loads the scene and finds FLIP, before anything
    /// is written.
    pub fn setup(&self) -> Result<Setup> {
        crate::image::check_output_dir("--out", &self.out)?;
        ensure!(!self.quality.is_empty(), "--quality names no quality");
        let qualities = self.quality.clone();
        ensure!(self.base_spp > 0, "--base-spp must be at least 1");
        ensure!(self.reference_spp > 0, "--reference-spp must be at least 1");
        ensure!(
            (1..=synth::MAX_SUPERSAMPLE).contains(&self.supersample),
            "--supersample {} must lie in 1..={}",
            self.supersample,
            synth::MAX_SUPERSAMPLE
        );
        let scene = Scene::load(&self.scene)?;
        let mut notes = Vec::new();
        if scene.dropped_triangles > 0 {
            notes.push(format!(
                "{} zero-area triangle(s) dropped while loading the scene",
                scene.dropped_triangles
            ));
        }
        notes.extend(scene.warnings.iter().cloned());
        if self.indirect != IndirectSource::Radiosity {
            notes.push(format!(
                "bases' diffuse indirect light: {} (the bake's default is radiosity)",
                self.indirect
            ));
        }
        let base_size = match self.base_size {
            Some(0) => bail!("--base-size must be at least 1"),
            Some(n) => n,
            None => {
                let fov = bake::size::narrowest_fov(&scene).with_context(|| {
                    format!(
                        "{} has no camera or walk path to size base images from: pass --base-size",
                        scene.source.display()
                    )
                })?;
                bake::size::base_size(BaseProjection::Sphere, self.size, fov)
            }
        };
        let flip = if self.no_flip {
            notes.push("FLIP left out (--no-flip)".to_string());
            None
        } else {
            Some(
                Flip::locate()
                    .context("FLIP is part of the report; pass --no-flip to leave it out")?,
            )
        };
        Ok(Setup {
            scene,
            qualities,
            flip,
            base_size,
            notes,
        })
    }

    /// The bake settings of quality `q`: full-sphere bases with the
    /// indirect light asked for, as `rangewalk bake` makes them, but
    /// sampled flat at `--base-spp` (not to a noise target), so that
    /// the experiments' sample counts are the ones their reports state.
    pub fn bake_settings(&self, q: Quality, base_size: u32) -> bake::Settings {
        bake::Settings {
            quality: q,
            size: base_size,
            spp: self.base_spp,
            projection: BaseProjection::Sphere,
            indirect: self.indirect,
            seed: BAKE_SEED,
            backend: self.backend,
            max_depth: None,
            planning: bake::Planning {
                view_fitness: self.view_fitness,
                ..Default::default()
            },
        }
    }
}

/// A ray engine over `scene` posed at the animation's start.
pub fn engine(scene: &Scene, backend: Backend) -> Result<Box<dyn InstancedEngine>> {
    accel::build(backend, &scene.geometry(), &scene.at(scene.animation.start))
        .with_context(|| format!("building the {backend} ray engine"))
}

/// Plans base views and times at quality `q` (id-images at the quality's
/// default resolution, a time list per view), timed.
pub fn plan_timed(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    q: Quality,
    view_fitness: ViewFitness,
) -> Result<(Plan, f64)> {
    let start = Instant::now();
    let plan = plan::make(
        scene,
        engine,
        &PlanOptions {
            quality: q,
            resolution: None,
            master_list: false,
            view_fitness,
        },
    )?;
    Ok((plan, start.elapsed().as_secs_f64()))
}

/// What rendering a bake's images cost, as its run measured it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BakeTiming {
    /// Simplification and the radiosity solves; `None` when an
    /// interrupted earlier run had solved them.
    pub radiosity_s: Option<f64>,
    /// Rendering the images this run rendered.
    pub render_s: f64,
    pub rendered: usize,
    /// Images in the bake.
    pub images: usize,
    pub samples: u64,
    pub rays: u64,
}

impl BakeTiming {
    pub fn per_image_s(&self) -> Option<f64> {
        (self.rendered > 0).then(|| self.render_s / self.rendered as f64)
    }

    /// Radiosity and every image, the images this run did not render
    /// counted at the mean cost of those it did.
    pub fn total_s(&self) -> Option<f64> {
        Some(self.radiosity_s? + self.per_image_s()? * self.images as f64)
    }
}

/// A complete bake and what it cost.
pub struct BakeRun {
    pub bake: Bake,
    /// `None` when the bake was found complete and its times were not
    /// recorded.
    pub timing: Option<BakeTiming>,
    /// Whether it was found complete in the output folder.
    pub reused: bool,
}

/// A bake's cost as reported.
#[derive(Clone, Debug)]
pub struct BakeCost {
    pub timing: Option<BakeTiming>,
    pub reused: bool,
}

impl BakeRun {
    pub fn cost(&self) -> BakeCost {
        BakeCost {
            timing: self.timing.clone(),
            reused: self.reused,
        }
    }
}

/// The bake of `plan` with `settings` in `dir`: reused when a complete one
/// of this scene, settings and plan is there, resumed when an unfinished
/// one is, else rendered afresh (anything else in `dir` is replaced).
pub fn bake_cached(
    scene: &Scene,
    dir: &Path,
    settings: &bake::Settings,
    plan: &Plan,
    engine: &mut dyn InstancedEngine,
) -> Result<BakeRun> {
    let fits = |m: &Manifest| -> Result<bool> {
        Ok(m.settings == *settings
            && m.plan.views == plan.views
            && m.scene_hash
                .differences(&ContentHash::of(scene)?)
                .is_empty())
    };
    let timing_path = dir.join(TIMING_FILE);
    if dir.exists() {
        match Manifest::read(dir) {
            Ok(m) if fits(&m)? && m.complete => {
                let bake = Bake::open(dir, scene)?;
                let timing = std::fs::read_to_string(&timing_path)
                    .ok()
                    .and_then(|s| serde_json::from_str(&s).ok());
                eprintln!("bake {}: complete, reused", dir.display());
                return Ok(BakeRun {
                    bake,
                    timing,
                    reused: true,
                });
            }
            Ok(m) if fits(&m)? => eprintln!("bake {}: resuming", dir.display()),
            _ => {
                eprintln!(
                    "bake {}: made from another scene, plan or settings; baking anew",
                    dir.display()
                );
                std::fs::remove_dir_all(dir)
                    .with_context(|| format!("removing {}", dir.display()))?;
            }
        }
    }
    eprintln!(
        "bake {}: {} view(s), {} image(s) of {}x{} at {} spp",
        dir.display(),
        plan.views.len(),
        plan.views.iter().map(|v| v.times.len()).sum::<usize>(),
        settings.size,
        settings.size,
        settings.spp
    );
    let summary = bake::run(scene, dir, settings, Shard::ALL, engine, |_| {
        Ok(plan.clone())
    })?;
    ensure!(
        summary.complete,
        "the bake in {} did not complete ({} of {} images)",
        dir.display(),
        summary.finished,
        summary.total
    );
    let timing = BakeTiming {
        radiosity_s: summary.radiosity_seconds,
        render_s: summary.render_seconds,
        rendered: summary.rendered,
        images: summary.total,
        samples: summary.samples,
        rays: summary.rays,
    };
    let json = serde_json::to_string_pretty(&timing).context("encoding bake times")?;
    crate::output::write_file(&timing_path, json)?;
    Ok(BakeRun {
        bake: Bake::open(dir, scene)?,
        timing: Some(timing),
        reused: false,
    })
}

/// The folder name of a quality's bake: `q0.3`.
pub fn quality_dir(prefix: &str, q: Quality) -> String {
    format!("{prefix}q{}", q.get())
}

/// One frame to synthesize: where it is seen from, when, and the name its
/// reference is cached under (with the time and size).
#[derive(Clone, Debug)]
pub struct Shot {
    pub camera: Camera,
    pub time: f32,
    pub name: String,
}

/// The path-traced reference of every shot, cached in `dir`.
pub fn references_of(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    shots: &[Shot],
    spp: u32,
    dir: &Path,
) -> Result<Vec<Reference>> {
    let mut out = Vec::with_capacity(shots.len());
    for s in shots {
        out.extend(reference::references(
            scene,
            engine,
            &s.camera,
            &s.name,
            &[s.time],
            spp,
            dir,
        )?);
    }
    Ok(out)
}

/// Spread `n` times evenly over `[start, end]`, both ends included.
pub fn spread(start: f32, end: f32, n: u32) -> Vec<f32> {
    match n {
        0 => Vec::new(),
        1 => vec![start],
        _ => (0..n)
            .map(|i| start + (end - start) * i as f32 / (n - 1) as f32)
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bake_totals_count_every_image() {
        let t = BakeTiming {
            radiosity_s: Some(2.0),
            render_s: 6.0,
            rendered: 3,
            images: 5,
            ..BakeTiming::default()
        };
        assert_eq!(t.per_image_s(), Some(2.0));
        assert_eq!(t.total_s(), Some(12.0));
        let resumed = BakeTiming {
            radiosity_s: None,
            ..t.clone()
        };
        assert_eq!(resumed.total_s(), None);
    }

    /// A rerun reports the bake times the first run recorded, read back
    /// from JSON: they must come back to the last bit. serde_json's default
    /// parser rounds some values one unit off (this one, measured in a run
    /// whose rerun then failed to match).
    #[test]
    fn recorded_bake_times_read_back_exactly() {
        let t = BakeTiming {
            radiosity_s: Some(3.7454124970000002),
            render_s: 0.184389814,
            ..BakeTiming::default()
        };
        let json = serde_json::to_string_pretty(&t).unwrap();
        let back: BakeTiming = serde_json::from_str(&json).unwrap();
        assert_eq!(back, t, "{json}");
    }

    fn seq(frames: Option<u32>) -> SequenceArgs {
        SequenceArgs {
            frames,
            time_interp: vec![TimeInterp::Linear],
            fill: Fill::Both,
        }
    }

    #[test]
    fn a_second_at_30_frames_per_second_is_31_frames() {
        let t = seq(None).times((0.0, 1.0), 30.0).unwrap();
        assert_eq!(t.len(), 31);
        assert_eq!((t[0], t[30]), (0.0, 1.0));
        assert!((t[10] - 1.0 / 3.0).abs() < 1e-6);
        assert_eq!(
            seq(Some(3)).times((0.0, 1.0), 30.0).unwrap(),
            [0.0, 0.5, 1.0]
        );
        assert!(seq(Some(0)).times((0.0, 1.0), 30.0).is_err());
        assert!(seq(None).times((0.0, 1.0), 0.0).is_err());
    }

    #[test]
    fn times_spread_over_an_interval() {
        assert_eq!(spread(0.0, 2.0, 3), [0.0, 1.0, 2.0]);
        assert_eq!(spread(0.5, 2.0, 1), [0.5]);
        assert!(spread(0.0, 1.0, 0).is_empty());
    }
}
