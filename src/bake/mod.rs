//! Base range images (paper §4.4): for every (view, time) of a plan, a
//! full-sphere (or 180° fisheye) range image rendered by the multipass
//! renderer: radiance, distance, object and primitive ids and normals, with
//! the diffuse-indirect part and the rest (direct and specular) as separate
//! layers for the synthesis. Each view's images hold only the window of
//! the projection that may see the scene ([`window`]).
//!
//! A bake directory holds the plan, the settings and a content hash of the
//! scene in `manifest.json` (see `docs/bake-format.md`), the radiosity
//! stage's bake in `radiosity/` (computed once and reused), and the images
//! in `images/`. Every file is written atomically. Each image's sampler is
//! seeded from (seed, view, time), so an image is the same whichever run,
//! shard or thread count renders it: a killed bake started again renders
//! only what is missing or damaged and ends identical to an uninterrupted
//! one, and shards `i/n` together make exactly the single-machine bake.
//! That is what lets a bake run as a Slurm job array (`slurm`), watched
//! and finished from the directory alone (`status`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, ensure, Context, Result};
use glam::Vec3;

use crate::accel::InstancedEngine;
use crate::camera::{Camera, Projection};
use crate::checksum::Fnv;
use crate::image::{self, RangeImage};
use crate::plan::Plan;
use crate::progress::{ProgressBar, ProgressStyle};
use crate::quality::Quality;
use crate::radiosity::lookup::IrradianceCache;
use crate::radiosity::temporal::TimeSeries;
use crate::radiosity::{self, store as radiosity_store, Simplified};
use crate::render::multipass::{self, Indirect};
use crate::render::noise::NoiseReport;
use crate::render::{Progress, RenderSettings};
use crate::scene::hash::ContentHash;
use crate::scene::Scene;

pub mod lock;
pub mod manifest;
pub mod sampling;
pub mod settings;
pub mod size;
pub mod slurm;
pub mod status;
pub mod window;

pub use manifest::{ImageEntry, Manifest};
pub use sampling::Sampling;
pub use settings::{BaseProjection, IndirectSource, Planning, Settings, Shard};
pub use window::BaseWindow;

/// The layers a base image holds besides its radiance.
pub const DIRECT: &str = "direct";
pub const INDIRECT: &str = "indirect";
pub const DIFFUSE_DIRECT: &str = "diffuse_direct";
/// The folder of a bake directory that holds its Slurm job scripts and logs.
pub const SLURM_DIR: &str = "slurm";

/// Samples per base-image pixel of `rangewalk bake` and the C ABI.
pub const DEFAULT_SPP: u32 = 16;
/// Frame size (`<W>x<H>`) base images are sized for when no size is given.
pub const DEFAULT_FRAME_SIZE: &str = "512x512";

/// The error of a bake stopped by its observer (see [`run_observed`]); the
/// bake directory stays resumable.
#[derive(Debug)]
pub struct Cancelled;

impl std::fmt::Display for Cancelled {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("the bake was cancelled; running it again resumes it")
    }
}

impl std::error::Error for Cancelled {}

/// What one run did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Summary {
    /// Images of this shard rendered now.
    pub rendered: usize,
    /// Images of this shard found finished and left alone.
    pub reused: usize,
    /// Images of the whole bake, and how many of them are finished.
    pub total: usize,
    pub finished: usize,
    pub complete: bool,
    pub samples: u64,
    /// Rays traced for shading (camera, shadow, bounce rays).
    pub rays: u64,
    pub render_seconds: f64,
    /// Radiosity stage: `None` where it was reused or not needed.
    pub radiosity_seconds: Option<f64>,
    /// Planning: `None` where the plan came from an earlier run.
    pub plan_seconds: Option<f64>,
    /// Temporary files that stopped runs had left, removed by this one.
    pub removed: usize,
    /// The noise the images rendered now reached, together.
    pub noise: Option<NoiseReport>,
}

/// The image's path relative to the bake directory.
fn image_file(view: usize, time_index: usize) -> String {
    format!("{}/v{view:03}-t{time_index:03}.exr", manifest::IMAGES)
}

/// Every (view, time) of the plan, views first.
pub fn image_entries(plan: &Plan) -> Vec<ImageEntry> {
    plan.views
        .iter()
        .enumerate()
        .flat_map(|(v, view)| {
            view.times
                .iter()
                .enumerate()
                .map(move |(j, &time)| ImageEntry {
                    view: v,
                    time_index: j,
                    time,
                    file: image_file(v, j),
                    fnv1a64: None,
                    noise: None,
                })
        })
        .collect()
}

/// The camera of view `position`: one orientation for every base image
/// (the scene's main view direction, so a fisheye looks where the viewer
/// does and a sphere has that direction at its centre).
pub fn base_camera(scene: &Scene, position: Vec3, settings: &Settings) -> Result<Camera> {
    let (forward, up) = view_frame(scene);
    let projection = match settings.projection {
        BaseProjection::Sphere => Projection::Sphere,
        BaseProjection::Fisheye => Projection::Fisheye,
    };
    Camera::looking(
        position,
        forward,
        up,
        projection,
        settings.size,
        settings.size,
    )
}

/// The first walk path's first view direction, else the first camera's,
/// else +z.
fn view_frame(scene: &Scene) -> (Vec3, Vec3) {
    if let Some(k) = scene.paths.first().and_then(|p| p.keys.first()) {
        return (k.direction, k.up);
    }
    if let Some(c) = scene.cameras.first() {
        return (c.direction, c.up);
    }
    (Vec3::Z, Vec3::Y)
}

/// The seed of one image's sampler, from the bake's seed, the view and the
/// time: independent of which run or shard renders it.
pub fn image_seed(seed: u64, view: usize, time: f32) -> u64 {
    let mut h = Fnv::default();
    h.write(&seed.to_le_bytes());
    h.write(&(view as u64).to_le_bytes());
    h.write(&time.to_bits().to_le_bytes());
    h.finish()
}

/// Starts a bake in `dir`, or resumes the one there: checks that it was
/// made from this scene with these settings, plans (with `plan`) only when
/// starting, solves radiosity once, renders this shard's missing or damaged
/// images, and marks the bake complete when no image of any shard is
/// missing. Every pixel takes `settings.spp` samples ([`Sampling::FLAT`]);
/// [`run_observed`] samples to a noise target.
pub fn run(
    scene: &Scene,
    dir: &Path,
    settings: &Settings,
    shard: Shard,
    engine: &mut dyn InstancedEngine,
    plan: impl FnOnce(&mut dyn InstancedEngine) -> Result<Plan>,
) -> Result<Summary> {
    run_observed(
        scene,
        dir,
        settings,
        &Sampling::FLAT,
        shard,
        engine,
        plan,
        &mut |_| true,
    )
}

/// [`run`] with `sampling`, telling `observe` on the calling thread the fraction of this
/// run's images finished: 0 before the first (after planning and
/// radiosity), then after each image. Answering `false` stops the run
/// before its next image with [`Cancelled`], leaving the bake to be
/// resumed; a run with nothing left to render never asks.
#[allow(clippy::too_many_arguments)]
pub fn run_observed(
    scene: &Scene,
    dir: &Path,
    settings: &Settings,
    sampling: &Sampling,
    shard: Shard,
    engine: &mut dyn InstancedEngine,
    plan: impl FnOnce(&mut dyn InstancedEngine) -> Result<Plan>,
    observe: &mut dyn FnMut(f32) -> bool,
) -> Result<Summary> {
    let mut summary = Summary::default();
    let what = if shard == Shard::ALL {
        "baking".to_string()
    } else {
        format!("baking shard {}/{}", shard.index, shard.count)
    };
    let me = lock::Holder::me(what, shard);
    // Registered while the manifest is checked under the bake's lock, and
    // for as long as this run renders.
    let (mut manifest, _running) = {
        // Hashed outside the lock, which shards take one after another.
        let hash = ContentHash::of(scene)?;
        let setup = lock_bake(dir, settings, sampling, &me)?;
        let manifest = start_or_resume(
            scene,
            &hash,
            dir,
            (settings, sampling),
            engine,
            plan,
            &mut summary,
            &setup,
        )?;
        let alone = setup.anyone().is_none();
        let running = setup.register(&me)?;
        if alone {
            summary.removed = setup.remove_temporaries()?;
        }
        (manifest, running)
    };
    let quality = settings.quality;
    summary.total = manifest.images.len();

    let mine: Vec<usize> = (0..manifest.images.len())
        .filter(|&k| shard.owns(k))
        .collect();
    let mut todo = Vec::new();
    // Images this run has read back or written itself need no second look.
    let mut checked = vec![false; manifest.images.len()];
    for &k in &mine {
        let e = &manifest.images[k];
        if manifest::verify(
            &dir.join(&e.file),
            e.fnv1a64.as_deref(),
            manifest.has_planes(),
        ) {
            summary.reused += 1;
            checked[k] = true;
        } else {
            todo.push(k);
        }
    }

    if !todo.is_empty() {
        let indirect = match settings.indirect {
            IndirectSource::Radiosity | IndirectSource::Gather => {
                let (s, series, seconds) = radiosity_once(scene, dir, quality, engine, &me)?;
                summary.radiosity_seconds = seconds;
                Some((s, series))
            }
            IndirectSource::Path => None,
        };
        let pixels: u64 = todo
            .iter()
            .map(|&k| manifest.windows[manifest.images[k].view].pixels())
            .sum();
        let bar = ProgressBar::new(pixels).with_style(
            ProgressStyle::with_template(
                "{msg} {bar:40} {percent}% of pixels, {elapsed} ({eta} left)",
            )
            .expect("progress template is valid"),
        );
        let start = Instant::now();
        let mut reports = Vec::with_capacity(todo.len());
        if !observe(0.0) {
            bar.finish_and_clear();
            return Err(Cancelled.into());
        }
        for (n, &k) in todo.iter().enumerate() {
            let e = manifest.images[k].clone();
            bar.set_message(format!("image {}/{}", n + 1, todo.len()));
            let (stats, report) = render_image(
                scene,
                &manifest,
                &e,
                settings,
                sampling,
                engine,
                indirect.as_ref(),
                dir,
                &bar,
            )
            .with_context(|| format!("baking {}", e.file))?;
            summary.rendered += 1;
            checked[k] = true;
            summary.samples += stats.samples;
            summary.rays += stats.rays;
            bar.suspend(|| eprintln!("{}: {report}", e.file));
            reports.push(report);
            summary.noise = NoiseReport::combine(&reports);
            if !observe((n + 1) as f32 / todo.len() as f32) && n + 1 < todo.len() {
                bar.finish_and_clear();
                return Err(Cancelled.into());
            }
        }
        bar.finish_and_clear();
        summary.render_seconds = start.elapsed().as_secs_f64();
    }

    // When no image of any shard is missing, check every image once more
    // and mark the bake complete.
    summary.finished = status::done(dir, &manifest);
    if summary.finished == summary.total && !manifest.complete {
        let bad = status::seal(dir, &mut manifest, &checked)?;
        if !bad.is_empty() {
            summary.finished -= bad.len();
            eprintln!(
                "warning: {} damaged since they were written: {}; run the bake again to re-render them",
                bad.len(),
                bad.join(", ")
            );
        }
    }
    // A bake sealed complete may have lost an image since.
    summary.complete = manifest.complete && summary.finished == summary.total;
    Ok(summary)
}

/// The object-space stages alone, run once before the image shards of a
/// distributed bake: starts the bake in `dir` (the plan and the manifest),
/// or checks the one there, and solves radiosity if the images need it and
/// it is not solved yet. Renders no image.
pub fn prepare(
    scene: &Scene,
    dir: &Path,
    settings: &Settings,
    sampling: &Sampling,
    engine: &mut dyn InstancedEngine,
    plan: impl FnOnce(&mut dyn InstancedEngine) -> Result<Plan>,
) -> Result<Summary> {
    let mut summary = Summary::default();
    let me = lock::Holder::me("preparing", Shard::ALL);
    // Held throughout: preparing is the serial part of the bake.
    let hash = ContentHash::of(scene)?;
    let setup = lock_bake(dir, settings, sampling, &me)?;
    let manifest = start_or_resume(
        scene,
        &hash,
        dir,
        (settings, sampling),
        engine,
        plan,
        &mut summary,
        &setup,
    )?;
    if setup.anyone().is_none() {
        summary.removed = setup.remove_temporaries()?;
    }
    if settings.indirect.uses_records() {
        summary.radiosity_seconds = radiosity_stage(scene, dir, settings.quality, engine)?.2;
    }
    summary.total = manifest.images.len();
    summary.finished = status::done(dir, &manifest);
    summary.complete = manifest.complete && summary.finished == summary.total;
    Ok(summary)
}

/// Takes the bake's lock (see [`lock`]) for its serial steps, first
/// refusing settings that cannot make a bake and a directory that holds
/// something else: no lock file is left for nothing, or in someone else's
/// folder.
fn lock_bake(
    dir: &Path,
    settings: &Settings,
    sampling: &Sampling,
    me: &lock::Holder,
) -> Result<lock::Setup> {
    let field = |f: &str| format!("settings.{f}");
    sampling.check(settings.spp, &field)?;
    ensure!(
        settings.size > 0,
        "settings.size 0: a base image needs a pixel"
    );
    if !dir.join(manifest::MANIFEST).exists() {
        check_fresh(dir)?;
    }
    lock::Setup::acquire(dir, me)
}

/// [`radiosity_stage`], solved by one run only: runs that start together
/// (shards, or a bake and its `--prepare`) would otherwise each solve it
/// and write it into the same temporary folder.
fn radiosity_once(
    scene: &Scene,
    dir: &Path,
    quality: Quality,
    engine: &mut dyn InstancedEngine,
    me: &lock::Holder,
) -> Result<(Simplified, TimeSeries, Option<f64>)> {
    let solved = || {
        dir.join(manifest::RADIOSITY)
            .join(radiosity_store::MANIFEST)
            .exists()
    };
    if solved() {
        return radiosity_stage(scene, dir, quality, engine);
    }
    let _setup = lock::Setup::acquire(dir, me)?;
    radiosity_stage(scene, dir, quality, engine)
}

/// Refuses to go on with the bake in `dir` when it was made from another
/// scene or with other settings, or when `dir` holds something that is no
/// bake; a missing or empty directory passes.
pub fn check_resumable(
    scene: &Scene,
    dir: &Path,
    settings: &Settings,
    sampling: &Sampling,
) -> Result<()> {
    sampling.check(settings.spp, &|f| format!("settings.{f}"))?;
    if !dir.join(manifest::MANIFEST).exists() {
        return check_fresh(dir);
    }
    check_fits(
        &Manifest::read(dir)?,
        dir,
        &ContentHash::of(scene)?,
        (settings, sampling),
    )
}

/// Refuses a directory without a bake that holds anything but the job
/// scripts of a distributed bake and what a bake stopped before its
/// manifest leaves (its lock, temporary files): it is someone else's.
fn check_fresh(dir: &Path) -> Result<()> {
    let ours = |name: &std::ffi::OsStr| {
        name == SLURM_DIR
            || name == lock::LOCK
            || name == lock::RUNNING
            || manifest::is_temporary(name)
            // `image::check_output_dir`'s probe of a run starting beside.
            || name.to_string_lossy().starts_with(".rangewalk-probe-")
    };
    let foreign = match dir.read_dir() {
        Ok(mut entries) => entries.any(|e| e.map_or(true, |e| !ours(&e.file_name()))),
        Err(_) => false,
    };
    if foreign {
        bail!(
            "{} exists and is not a bake (no {}); refusing to write into it",
            dir.display(),
            manifest::MANIFEST
        );
    }
    Ok(())
}

/// The bake's manifest: read and checked against this scene and these
/// settings, or, when starting, planned (with `plan`) and written; under
/// the bake's lock (`_setup`), so that runs started together make one.
#[allow(clippy::too_many_arguments)]
fn start_or_resume(
    scene: &Scene,
    hash: &ContentHash,
    dir: &Path,
    (settings, sampling): (&Settings, &Sampling),
    engine: &mut dyn InstancedEngine,
    plan: impl FnOnce(&mut dyn InstancedEngine) -> Result<Plan>,
    summary: &mut Summary,
    setup: &lock::Setup,
) -> Result<Manifest> {
    let manifest = if dir.join(manifest::MANIFEST).exists() {
        let m = Manifest::read(dir)?;
        if let Err(e) = check_fits(&m, dir, hash, (settings, sampling)) {
            // Name who is baking it now, if anyone: the likely author.
            return Err(match setup.anyone() {
                Some(h) => anyhow::anyhow!("{e:#}; it is being baked now by {h}"),
                None => e,
            });
        }
        m
    } else {
        check_fresh(dir)?;
        let start = Instant::now();
        let plan = plan(engine)?;
        summary.plan_seconds = Some(start.elapsed().as_secs_f64());
        ensure!(!plan.views.is_empty(), "the plan has no views");
        for (i, v) in plan.views.iter().enumerate() {
            ensure!(!v.times.is_empty(), "the plan gives view {i} no times");
        }
        let positions: Vec<Vec3> = plan.views.iter().map(|v| v.position).collect();
        let space = window::viewpoints(scene, &positions);
        // Every view's times: a frame blends the sky of bases of several
        // views, and each must hold the directions the others may see
        // geometry in at theirs.
        let mut times: Vec<f32> = plan.views.iter().flat_map(|v| v.times.clone()).collect();
        times.sort_by(f32::total_cmp);
        times.dedup();
        let windows = plan
            .views
            .iter()
            .map(|v| {
                if settings.planning.whole {
                    return Ok(BaseWindow::whole(settings.size));
                }
                let camera = base_camera(scene, v.position, settings)?;
                Ok(window::find(scene, &camera, &times, space))
            })
            .collect::<Result<Vec<_>>>()?;
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let m = Manifest {
            format: manifest::FORMAT.into(),
            version: manifest::VERSION,
            scene: std::fs::canonicalize(&scene.source).unwrap_or_else(|_| scene.source.clone()),
            scene_hash: hash.clone(),
            settings: *settings,
            sampling: *sampling,
            windows,
            images: image_entries(&plan),
            plan,
            complete: false,
        };
        m.write(dir)?;
        m
    };
    std::fs::create_dir_all(dir.join(manifest::IMAGES))
        .with_context(|| format!("creating {}", dir.join(manifest::IMAGES).display()))?;
    Ok(manifest)
}

/// Refuses a bake made from another scene or with other settings, saying
/// what differs.
fn check_fits(
    m: &Manifest,
    dir: &Path,
    hash: &ContentHash,
    (settings, sampling): (&Settings, &Sampling),
) -> Result<()> {
    let changes = m.scene_hash.differences(hash);
    if !changes.is_empty() {
        bail!(
            "{} was baked from {} and the scene differs from it: {}",
            dir.display(),
            m.scene.display(),
            changes.join(", ")
        );
    }
    let (was, now) = (m.settings.resolved(), settings.resolved());
    if was != now {
        bail!(
            "{} was baked with other settings ({}); use them to resume it, or another directory",
            dir.display(),
            describe_difference(&was, &now)
        );
    }
    if m.sampling.target(was.spp) != sampling.target(now.spp) {
        bail!(
            "{} was baked with other settings ({}, not {}); use them to resume it, or another directory",
            dir.display(),
            m.sampling.describe(),
            sampling.describe()
        );
    }
    Ok(())
}

fn describe_difference(was: &Settings, now: &Settings) -> String {
    let mut out = Vec::new();
    let mut diff = |name: &str, a: String, b: String| {
        if a != b {
            out.push(format!("--{name} {a}, not {b}"));
        }
    };
    diff("quality", was.quality.to_string(), now.quality.to_string());
    diff("size", was.size.to_string(), now.size.to_string());
    diff("spp", was.spp.to_string(), now.spp.to_string());
    diff(
        "projection",
        format!("{:?}", was.projection).to_lowercase(),
        format!("{:?}", now.projection).to_lowercase(),
    );
    diff(
        "indirect",
        format!("{:?}", was.indirect).to_lowercase(),
        format!("{:?}", now.indirect).to_lowercase(),
    );
    diff("seed", was.seed.to_string(), now.seed.to_string());
    diff("backend", was.backend.to_string(), now.backend.to_string());
    diff(
        "max-depth",
        format!("{:?}", was.max_depth),
        format!("{:?}", now.max_depth),
    );
    let (a, b) = (&was.planning, &now.planning);
    let side = |r: Option<u32>| r.map_or("default".into(), |r| r.to_string());
    diff("resolution", side(a.resolution), side(b.resolution));
    diff(
        "view-fitness",
        a.view_fitness.to_string(),
        b.view_fitness.to_string(),
    );
    if a.whole != b.whole {
        out.push(
            if a.whole {
                "--whole-bases, not bases cropped to what they may see"
            } else {
                "bases cropped to what they may see, not --whole-bases"
            }
            .into(),
        );
    }
    if a.master_list != b.master_list {
        out.push(
            if a.master_list {
                "--master-list (one time list for every view), not a list per view"
            } else {
                "a time list per view, not --master-list"
            }
            .into(),
        );
    }
    out.join(", ")
}

/// The radiosity bake in `dir/radiosity`, solved and saved first if it is
/// not there; returns the seconds spent solving (`None` when reused).
fn radiosity_stage(
    scene: &Scene,
    dir: &Path,
    quality: Quality,
    engine: &mut dyn InstancedEngine,
) -> Result<(Simplified, TimeSeries, Option<f64>)> {
    let path = dir.join(manifest::RADIOSITY);
    if path.join(radiosity_store::MANIFEST).exists() {
        let (simplified, series, _) = radiosity_store::load_for(&path, scene, Some(quality))?;
        return Ok((simplified, series, None));
    }
    let start = Instant::now();
    eprintln!("radiosity: simplifying and solving at quality {quality}");
    engine.set_transforms(&scene.at(scene.animation.start))?;
    let (simplified, series) = radiosity::simplify_and_decompose(scene, engine, quality)?;
    radiosity_store::save(&path, scene, &simplified, &series)?;
    Ok((simplified, series, Some(start.elapsed().as_secs_f64())))
}

#[allow(clippy::too_many_arguments)]
fn render_image(
    scene: &Scene,
    manifest: &Manifest,
    e: &ImageEntry,
    settings: &Settings,
    sampling: &Sampling,
    engine: &mut dyn InstancedEngine,
    indirect: Option<&(Simplified, TimeSeries)>,
    dir: &Path,
    bar: &ProgressBar,
) -> Result<(crate::render::RenderStats, NoiseReport)> {
    let view = &manifest.plan.views[e.view];
    let camera = manifest.windows[e.view]
        .crop(&base_camera(scene, view.position, settings)?)
        .with_context(|| format!("`windows[{}]`", e.view))?;
    engine
        .set_transforms(&scene.at(e.time))
        .with_context(|| format!("posing the scene at t = {}", e.time))?;
    let render_settings = RenderSettings {
        spp: settings.spp,
        max_depth: settings.max_depth,
        seed: image_seed(settings.seed, e.view, e.time),
    };
    let cache = indirect
        .map(|(s, series)| IrradianceCache::new(s, &series.indirect_at(e.time)))
        .transpose()?;
    let source = match (&cache, settings.indirect) {
        (Some(c), IndirectSource::Gather) => Indirect::Gathered(c),
        (Some(c), _) => Indirect::Records(c),
        (None, _) => Indirect::Traced,
    };
    let out = multipass::render_base(
        scene,
        &*engine,
        &camera,
        e.time,
        &render_settings,
        source,
        sampling.target(settings.spp),
        Progress::Pixels(bar),
    )?;
    let direct: Vec<Vec3> = out
        .image
        .radiance
        .iter()
        .zip(&out.indirect)
        .map(|(l, i)| *l - *i)
        .collect();
    let path = dir.join(&e.file);
    let sum = image::write_exr_with_layers(
        &path,
        &out.image,
        &[
            (DIRECT, &direct),
            (INDIRECT, &out.indirect),
            (DIFFUSE_DIRECT, &out.diffuse_direct),
        ],
    )?;
    // Bakes of older versions resumed by this one are read as they were
    // written: before version 6 from their EXRs (a planes file there would
    // never be read), before version 8 from range images' planes files.
    let planes = manifest::planes_path(&path);
    if manifest.has_base_planes() {
        let base = image::planes_file::BasePlanes::of(out.image);
        image::planes_file::write_base(&planes, &base, &manifest::hex(sum))?;
    } else if manifest.has_planes() {
        image::planes_file::write(&planes, &out.image, &manifest::hex(sum))?;
    }
    let report = out.sampling.report;
    sampling::write_report(&path, &report)?;
    crate::output::write_file(
        &manifest::checksum_path(&path),
        manifest::hex(sum).as_bytes(),
    )?;
    Ok((out.stats, report))
}

/// A complete bake, opened for reading against the scene in hand.
#[derive(Debug)]
pub struct Bake {
    pub dir: PathBuf,
    pub manifest: Manifest,
}

/// One base image read back.
#[derive(Debug)]
pub struct BaseImage {
    pub image: RangeImage,
    /// Emission, direct light and traced specular reflection.
    pub direct: Vec<Vec3>,
    /// Diffuse indirect light at the surfaces seen.
    pub indirect: Vec<Vec3>,
    /// Direct light reflected by the diffuse lobe of the surfaces seen
    /// (part of `direct`).
    pub diffuse_direct: Vec<Vec3>,
}

impl Bake {
    /// Opens the bake in `dir`; refuses one that is unfinished or was made
    /// from a scene that differs from `scene`, saying what changed.
    pub fn open(dir: &Path, scene: &Scene) -> Result<Bake> {
        let manifest = Manifest::read(dir)?;
        let changes = manifest.scene_hash.differences(&ContentHash::of(scene)?);
        if !changes.is_empty() {
            bail!(
                "{} was baked from {}, and {} differs from it: {}",
                dir.display(),
                manifest.scene.display(),
                scene.source.display(),
                changes.join(", ")
            );
        }
        if !manifest.complete {
            bail!(
                "{} is not complete: run the same `rangewalk bake` command again to finish it",
                dir.display()
            );
        }
        Ok(Bake {
            dir: dir.to_path_buf(),
            manifest,
        })
    }

    /// Reads image `k` (manifest order) with its three light layers,
    /// checking its checksum.
    pub fn read(&self, k: usize) -> Result<BaseImage> {
        let (image, layers) = self.read_layers(k, &[DIRECT, INDIRECT, DIFFUSE_DIRECT])?;
        let [direct, indirect, diffuse_direct]: [Vec<Vec3>; 3] =
            layers.try_into().expect("three layers asked");
        Ok(BaseImage {
            image,
            direct,
            indirect,
            diffuse_direct,
        })
    }

    /// What synthesis reads of image `k` (`BasePlanes::of` its range image), read from
    /// its planes file, each chunk checked as it is read; only bakes of
    /// version 8 on have such planes files.
    pub fn read_base(&self, k: usize) -> Result<image::planes_file::BasePlanes> {
        let e = self.entry(k)?;
        let path = manifest::planes_path(&self.dir.join(&e.file));
        ensure!(
            self.manifest.has_base_planes(),
            "{}: a version-{} bake's planes files hold range images, not bases",
            self.dir.display(),
            self.manifest.version
        );
        // `open` refuses incomplete bakes: every image has its checksum.
        let sum = e.fnv1a64.as_deref().unwrap_or_default();
        let base = image::planes_file::read_base(&path, sum).map_err(|err| {
            anyhow::anyhow!(
                "{err:#}; run the bake again (the same `rangewalk bake` command) to re-render it"
            )
        })?;
        self.check_window(e, &path, &base.meta.camera)?;
        Ok(base)
    }

    /// Image `k`'s range image without its light layers: from its planes
    /// file, each chunk checked as it is read, where the bake's planes
    /// files hold range images (versions 6 and 7), else decoded from its
    /// EXR and checked whole.
    pub fn read_range(&self, k: usize) -> Result<RangeImage> {
        if !self.manifest.has_planes() || self.manifest.has_base_planes() {
            return Ok(self.read_layers(k, &[])?.0);
        }
        let e = self.entry(k)?;
        let path = manifest::planes_path(&self.dir.join(&e.file));
        // `open` refuses incomplete bakes: every image has its checksum.
        let sum = e.fnv1a64.as_deref().unwrap_or_default();
        let image = image::planes_file::read(&path, sum).map_err(|err| {
            anyhow::anyhow!(
                "{err:#}; run the bake again (the same `rangewalk bake` command) to re-render it"
            )
        })?;
        self.check_window(e, &path, &image.meta.camera)?;
        Ok(image)
    }

    fn entry(&self, k: usize) -> Result<&ImageEntry> {
        self.manifest
            .images
            .get(k)
            .with_context(|| format!("{}: no image {k}", self.dir.display()))
    }

    /// Reads image `k` and the named light layers (of [`DIRECT`],
    /// [`INDIRECT`], [`DIFFUSE_DIRECT`]), checking its checksum.
    pub fn read_layers(&self, k: usize, layers: &[&str]) -> Result<(RangeImage, Vec<Vec<Vec3>>)> {
        let e = self.entry(k)?;
        let path = self.dir.join(&e.file);
        let damaged = || {
            anyhow::anyhow!(
                "{}: missing or damaged (its checksum differs from the manifest's); run the bake again to re-render it",
                path.display()
            )
        };
        let read = image::read_exr_with_layers_hashed(&path, layers);
        let Ok((image, layers, sum)) = read else {
            return Err(damaged());
        };
        if e.fnv1a64.as_deref() != Some(manifest::hex(sum).as_str()) {
            return Err(damaged());
        }
        self.check_window(e, &path, &image.meta.camera)?;
        Ok((image, layers))
    }

    fn check_window(&self, e: &ImageEntry, path: &Path, camera: &Camera) -> Result<()> {
        // The checksum holds the window the image was written with; the
        // manifest's must be that one, or pixels would be put in the
        // wrong directions.
        let window = self.manifest.windows.get(e.view);
        let (x, y) = camera.origin();
        let held = BaseWindow {
            x,
            y,
            width: camera.width,
            height: camera.height,
        };
        let size = self.manifest.settings.size;
        if window != Some(&held) || camera.full_size() != (size, size) {
            let (fw, fh) = camera.full_size();
            bail!(
                "{}: its data window, {held} of a {fw}x{fh} display window, is not the manifest's `windows[{}]`, {} of {size}x{size}: the bake is inconsistent; bake it again into a new directory",
                path.display(),
                e.view,
                window.map_or("absent".to_string(), |w| w.to_string())
            );
        }
        Ok(())
    }
}
