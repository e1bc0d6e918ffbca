//! The `rangewalk` command line.

mod cli;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand, ValueEnum};

use rangewalk::accel::{self, Backend, InstancedEngine};
use rangewalk::bake::{self, BaseProjection, IndirectSource, Shard};
use rangewalk::camera::{Camera, Projection};
use rangewalk::image::{self, RangeImage};
use rangewalk::plan::ViewFitness;
use rangewalk::radiosity::lookup::IrradianceCache;
use rangewalk::radiosity::temporal::{self, TimeSeries};
use rangewalk::radiosity::{self, bake as radiosity_bake, Quality, Simplified};
use rangewalk::render::{self, multipass, RenderSettings, RenderStats};
use rangewalk::scene::{Bsdf, Light, Scene};
use strum::EnumMessage;

#[derive(Parser)]
#[command(
    name = "rangewalk",
    version,
    about = "Image-based global illumination for animated scenes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render the scene at one time: path traced (the reference), or with
    /// indirect light from radiosity (multipass).
    Render {
        scene: PathBuf,
        #[command(flatten)]
        view: ViewArgs,
        /// Samples per pixel.
        #[arg(long, default_value_t = 64)]
        spp: u32,
        /// Output range image (OpenEXR: radiance, distance, ids, normals).
        #[arg(long)]
        out: PathBuf,
        #[arg(long, value_parser = cli::choice::<Backend>(), default_value_t = Backend::default_available())]
        backend: Backend,
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Longest path, counted as Mitsuba's `max_depth` (1: emitters only,
        /// 2: direct light). Unlimited by default: Russian roulette ends paths.
        #[arg(long)]
        max_depth: Option<u32>,
        /// Also write a tone-mapped PNG preview here.
        #[arg(long)]
        preview: Option<PathBuf>,
        /// Also write Radiance RGBE radiance here.
        #[arg(long)]
        hdr: Option<PathBuf>,
        /// Exposure of the preview in stops (radiance scaled by 2^exposure).
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        exposure: f32,
        #[command(flatten)]
        indirect: IndirectArgs,
    },
    /// Write the scene at one time for another renderer.
    Export {
        scene: PathBuf,
        #[command(flatten)]
        view: ViewArgs,
        #[arg(long, default_value_t = 64)]
        spp: u32,
        #[arg(long)]
        max_depth: Option<u32>,
        #[arg(long, value_enum)]
        format: ExportFormat,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
    },
    /// Describe a scene and which stages it needs.
    Info { scene: PathBuf },
    /// Simplify the scene, solve radiosity over the animation's time list
    /// and store the result in a bake directory.
    Radiosity {
        scene: PathBuf,
        /// Quality in [0, 1]: finer simplification, more solves.
        #[arg(long, default_value_t = radiosity::DEFAULT_QUALITY)]
        quality: f32,
        /// Bake directory to write (replaced if it holds an earlier bake).
        #[arg(long)]
        out: PathBuf,
        #[arg(long, value_parser = cli::choice::<Backend>(), default_value_t = Backend::default_available())]
        backend: Backend,
    },
    /// Choose base views and their time lists from id-image fitness
    /// (paper §4.1-4.2) and write the plan as JSON.
    Plan(PlanArgs),
    /// Render the base range images of every (view, time) of the plan
    /// (paper §4.4) into a bake directory; resumes an unfinished bake.
    Bake(BakeArgs),
    /// Write (and with --submit, submit) Slurm job scripts that bake on a
    /// cluster: one job for the plan and radiosity, an array of bake tasks,
    /// one job that checks every image and marks the bake complete.
    Slurm(SlurmArgs),
    /// Synthesize one frame of a named camera at a time from a bake's base
    /// images (view reprojection and time interpolation).
    Synth(cli::synth::SynthArgs),
    /// Synthesize every frame of a walk path from a bake: range images,
    /// previews, an animated preview and a summary.
    Walk(cli::synth::WalkArgs),
    /// Walk through a bake in a window, in real time: keys and mouse move
    /// and turn, time plays; or play a path or an input script.
    View(cli::view::ViewArgs),
    /// Error of range images against a reference range image: LRMS and
    /// bias of luminance (the paper's measure), and the LRMS of 8x8-block
    /// means and its 99th percentile over blocks. Each image must have the
    /// reference's size, projection and camera (its pixels must look where
    /// the reference's do); another scene time is a warning.
    Compare {
        reference: PathBuf,
        #[arg(required = true)]
        images: Vec<PathBuf>,
    },
    /// Measure a stage against path-traced references and write a report.
    Experiment {
        #[command(subcommand)]
        experiment: cli::experiment::Experiment,
    },
}

#[derive(clap::Args)]
struct IndirectArgs {
    /// Where diffuse indirect light comes from: traced paths, or radiosity
    /// records looked up by the multipass renderer.
    #[arg(long, value_enum, default_value_t = IndirectArg::Path)]
    indirect: IndirectArg,
    /// Quality in [0, 1] of the radiosity stages (with `--indirect
    /// radiosity`): 0.5 if not given, or the bake's.
    #[arg(long)]
    quality: Option<f32>,
    /// Bake directory: used if it exists, written if not (with
    /// `--indirect radiosity`).
    #[arg(long)]
    bake: Option<PathBuf>,
}

impl IndirectArgs {
    fn check(&self) -> Result<()> {
        if self.indirect == IndirectArg::Path {
            if self.bake.is_some() {
                bail!("--bake applies to --indirect radiosity only");
            }
            if self.quality.is_some() {
                bail!("--quality applies to --indirect radiosity only");
            }
        }
        Ok(())
    }
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum IndirectArg {
    Path,
    Radiosity,
}

#[derive(clap::Args)]
struct ViewArgs {
    /// Scene time in seconds (within the animation of an animated scene).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    time: f32,
    /// Named camera of the scene.
    #[arg(long, default_value = "main")]
    camera: String,
    /// Image size, `<W>x<H>`.
    #[arg(long, default_value = "256x256", value_parser = image::parse_size)]
    size: (u32, u32),
    /// Projection; the camera's field of view applies to `perspective` only.
    #[arg(long, value_enum, default_value_t = ProjectionArg::Perspective)]
    projection: ProjectionArg,
}

#[derive(Clone, Copy, ValueEnum)]
enum ProjectionArg {
    Perspective,
    Fisheye,
    Sphere,
}

#[derive(Clone, Copy, ValueEnum)]
enum ExportFormat {
    Mitsuba,
}

impl ViewArgs {
    fn camera(&self, scene: &Scene) -> Result<Camera> {
        let desc = scene.camera(&self.camera)?;
        let (w, h) = self.size;
        match self.projection {
            ProjectionArg::Perspective => desc.perspective(w, h),
            ProjectionArg::Fisheye => desc.with_projection(Projection::Fisheye, w, h),
            ProjectionArg::Sphere => desc.with_projection(Projection::Sphere, w, h),
        }
    }

    fn check_time(&self, scene: &Scene) -> Result<()> {
        scene.check_time(self.time).context("--time")
    }
}

/// A ray engine over the scene posed at the animation's start.
fn engine_at_start(s: &Scene, backend: Backend) -> Result<Box<dyn InstancedEngine>> {
    accel::build(backend, &s.geometry(), &s.at(s.animation.start))
        .with_context(|| format!("building the {backend} ray engine"))
}

fn load(path: &PathBuf) -> Result<Scene> {
    let scene = Scene::load(path)?;
    if scene.dropped_triangles > 0 {
        eprintln!(
            "warning: {}: dropped {} zero-area triangle(s)",
            path.display(),
            scene.dropped_triangles
        );
    }
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    Ok(scene)
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render {
            scene,
            view,
            spp,
            out,
            backend,
            seed,
            max_depth,
            preview,
            hdr,
            exposure,
            indirect,
        } => {
            if spp == 0 {
                bail!("--spp must be at least 1");
            }
            indirect.check()?;
            image::check_output("--out", &out, image::OutputKind::Exr)?;
            if let Some(dir) = indirect
                .bake
                .as_ref()
                .filter(|d| !d.join(radiosity_bake::MANIFEST).exists())
            {
                image::check_output_dir("--bake", dir)?;
            }
            if let Some(p) = &preview {
                image::check_output("--preview", p, image::OutputKind::Png)?;
            }
            if let Some(p) = &hdr {
                image::check_output("--hdr", p, image::OutputKind::Hdr)?;
            }
            let s = load(&scene)?;
            view.check_time(&s)?;
            let camera = view.camera(&s)?;
            let build = Instant::now();
            let mut engine = accel::build(backend, &s.geometry(), &s.at(view.time))
                .with_context(|| format!("building the {backend} ray engine"))?;
            let build_s = build.elapsed().as_secs_f64();
            let settings = RenderSettings {
                spp,
                max_depth,
                seed,
            };
            let (img, stats) = match indirect.indirect {
                IndirectArg::Path => {
                    render::render(&s, engine.as_ref(), &camera, view.time, &settings)?
                }
                IndirectArg::Radiosity => render_multipass(
                    &s,
                    engine.as_mut(),
                    &camera,
                    view.time,
                    &settings,
                    &indirect,
                )?,
            };
            write_outputs(&out, &img, preview, hdr, exposure)?;
            println!(
                "{}: {}x{} at t = {} s, {} spp, {}, backend {}: {:.3} s ({:.3} s build), {:.3} M samples/s, {:.2} M rays/s",
                out.display(),
                camera.width,
                camera.height,
                view.time,
                spp,
                match indirect.indirect {
                    IndirectArg::Path => "path traced",
                    IndirectArg::Radiosity => "multipass with radiosity indirect",
                },
                backend,
                stats.seconds,
                build_s,
                stats.samples as f64 / stats.seconds / 1e6,
                stats.rays as f64 / stats.seconds / 1e6,
            );
        }
        Command::Export {
            scene,
            view,
            spp,
            max_depth,
            format,
            out,
        } => {
            image::check_output_dir("--out", &out)?;
            rangewalk::output::check_only(&out, &rangewalk::export::mitsuba::CONTENTS)?;
            let s = load(&scene)?;
            view.check_time(&s)?;
            let camera = view.camera(&s)?;
            match format {
                ExportFormat::Mitsuba => rangewalk::export::mitsuba::export(
                    &s, view.time, &camera, spp, max_depth, &out,
                )?,
            }
            println!(
                "{}: Mitsuba 3 scene at t = {} s",
                out.join("scene.xml").display(),
                view.time
            );
        }
        Command::Info { scene } => info(&load(&scene)?),
        Command::Radiosity {
            scene,
            quality,
            out,
            backend,
        } => {
            let q = Quality::new(quality).context("--quality")?;
            image::check_output_dir("--out", &out)?;
            let s = load(&scene)?;
            let mut engine = engine_at_start(&s, backend)?;
            let (simplified, series) = radiosity::simplify_and_decompose(&s, engine.as_mut(), q)?;
            radiosity_bake::save(&out, &s, &simplified, &series)?;
            report_radiosity(&s, &simplified, &series);
            println!("bake written to {}", out.display());
        }
        Command::Experiment { experiment } => cli::experiment::run(experiment)?,
        Command::Plan(args) => plan(args)?,
        Command::Bake(args) => bake_command(args)?,
        Command::Slurm(args) => slurm_command(args)?,
        Command::Compare { reference, images } => {
            use rangewalk::eval::metrics;
            let r = image::read_exr(&reference)?;
            // The scene's size for telling one camera position from another.
            let scale = r.distance.iter().copied().fold(0.0, f32::max);
            for p in images {
                let t = image::read_exr(&p)?;
                let against = || format!("{} against {}", p.display(), reference.display());
                let e = metrics::check_same_view(&t.meta, &r.meta, scale)
                    .and_then(|()| metrics::compare(&t, &r, None))
                    .with_context(against)?;
                if let Some(w) = metrics::time_warning(&t.meta, &r.meta) {
                    eprintln!("warning: {}: {w}", against());
                }
                println!(
                    "{}: LRMS {:.4}, bias {:+.4}, 8x8-block LRMS {:.4}, block p99 {:.4} over {} pixels",
                    p.display(),
                    e.lrms,
                    e.bias,
                    e.block_lrms,
                    e.block_p99,
                    e.pixels
                );
            }
        }
        Command::Synth(args) => cli::synth::synth(&args)?,
        Command::Walk(args) => cli::synth::walk(&args)?,
        Command::View(args) => cli::view::view(&args)?,
    }
    Ok(())
}

fn write_outputs(
    out: &Path,
    img: &RangeImage,
    preview: Option<PathBuf>,
    hdr: Option<PathBuf>,
    exposure: f32,
) -> Result<()> {
    image::write_exr(out, img)?;
    if let Some(p) = preview {
        image::write_png_preview(&p, img.width, img.height, &img.radiance, exposure)?;
    }
    if let Some(p) = hdr {
        image::write_hdr(&p, img.width, img.height, &img.radiance)?;
    }
    Ok(())
}

/// The multipass render: indirect light from the bake (or computed, and
/// baked if asked), interpolated to `time`.
fn render_multipass(
    s: &Scene,
    engine: &mut dyn InstancedEngine,
    camera: &Camera,
    time: f32,
    settings: &RenderSettings,
    args: &IndirectArgs,
) -> Result<(RangeImage, RenderStats)> {
    let q = args
        .quality
        .map(|q| Quality::new(q).context("--quality"))
        .transpose()?;
    let (simplified, series) = match &args.bake {
        Some(dir) if dir.join(radiosity_bake::MANIFEST).exists() => load_bake(s, dir, q)?,
        bake_dir => {
            let q = q.unwrap_or(Quality::new(radiosity::DEFAULT_QUALITY)?);
            let (simplified, series) = radiosity::simplify_and_decompose(s, engine, q)?;
            if let Some(dir) = bake_dir {
                radiosity_bake::save(dir, s, &simplified, &series)?;
                eprintln!("bake written to {}", dir.display());
            }
            (simplified, series)
        }
    };
    engine
        .set_transforms(&s.at(time))
        .with_context(|| format!("posing the scene at t = {time}"))?;
    let cache = IrradianceCache::new(&simplified, &series.indirect_at(time))?;
    multipass::render(s, &*engine, camera, time, settings, &cache)
}

/// A bake made for this scene (at quality `q`, if given).
fn load_bake(s: &Scene, dir: &Path, q: Option<Quality>) -> Result<(Simplified, TimeSeries)> {
    let (simplified, series, info) = radiosity_bake::load_for(dir, s, q)?;
    eprintln!(
        "using the bake in {} (quality {}, {} solutions)",
        dir.display(),
        info.quality,
        series.solutions.len()
    );
    Ok((simplified, series))
}

/// What the object-space stages did, and which were skipped and why.
fn report_radiosity(s: &Scene, simplified: &Simplified, series: &TimeSeries) {
    let st = &simplified.stats;
    println!(
        "simplification: {} initial surfaces, {} pruned, {} final; {} visibility rays; {:.3} s",
        st.initial_surfaces, st.pruned_surfaces, st.final_surfaces, st.visibility_rays, st.seconds
    );
    println!(
        "  {} patches, {} irradiance records",
        simplified.patches.len(),
        simplified.records.len()
    );
    let times: Vec<String> = series.times.iter().map(|t| t.to_string()).collect();
    println!("time list ({}): {}", times.len(), times.join(", "));
    for sol in &series.solutions {
        let ss = &sol.stats;
        println!(
            "  solve t = {}: {} elements, {} links, {} iterations, residual {:.2e}, {} shadow rays, {:.3} s",
            sol.time, ss.elements, ss.links, ss.iterations, ss.residual, ss.shadow_rays, ss.seconds
        );
    }
    let d = &series.stats;
    let limits = Quality::new(series.quality)
        .ok()
        .map(temporal::Thresholds::for_quality);
    if d.static_scene {
        println!("temporal decomposition skipped: static scene, one solution");
    } else if d.intervals.is_empty() {
        println!("temporal decomposition skipped: the animation has no duration");
    } else {
        println!(
            "temporal decomposition: {} solves, depth {} of {} allowed, {:.3} s",
            d.solves, d.depth, d.max_depth, d.seconds
        );
        if let Some(l) = limits {
            println!(
                "  split while relative RMS > {:.4} or fewer than {:.0}% of records unchanged",
                l.relative_rms,
                100.0 * l.unchanged_fraction
            );
        }
        for i in &d.intervals {
            let incoherent = limits.is_some_and(|l| {
                i.relative_rms > l.relative_rms || i.unchanged < l.unchanged_fraction
            });
            println!(
                "  [{}, {}] depth {}: relative RMS {:.4}, {:.1}% records unchanged: {}",
                i.t0,
                i.t1,
                i.depth,
                i.relative_rms,
                100.0 * i.unchanged,
                match (i.split, incoherent) {
                    (true, _) => "split",
                    (false, true) => "kept at the depth limit",
                    (false, false) => "coherent",
                }
            );
        }
    }
    if !s.has_specular() {
        println!("specular rays skipped: no glossy or mirror surfaces");
    }
}

fn info(s: &Scene) {
    let tris: usize = s.objects.iter().map(|o| o.mesh.triangles.len()).sum();
    println!("{}", s.source.display());
    println!(
        "  {} objects, {} triangles, {} materials",
        s.objects.len(),
        tris,
        s.materials.len()
    );
    for o in &s.objects {
        let m = &s.materials[o.material];
        let kind = match m.bsdf {
            Bsdf::Diffuse { .. } => "diffuse",
            Bsdf::Glossy { .. } => "glossy",
            Bsdf::Mirror { .. } => "mirror",
        };
        println!(
            "  {:<12} {:>7} triangles  {:<10} {}{}",
            o.name,
            o.mesh.triangles.len(),
            m.name,
            kind,
            match (m.emission.is_some(), o.motion.is_static()) {
                (true, true) => ", emits",
                (true, false) => ", emits, moves",
                (false, false) => ", moves",
                (false, true) => "",
            }
        );
    }
    for l in &s.lights {
        match l {
            Light::Point {
                position,
                intensity,
            } => println!("  point light at {position}, intensity {intensity}"),
            Light::Sun {
                direction,
                radiance,
                angular_diameter_deg,
            } => {
                println!("  sun towards {direction}, radiance {radiance}, {angular_diameter_deg}°")
            }
        }
    }
    let cams: Vec<&str> = s.cameras.iter().map(|c| c.name.as_str()).collect();
    println!("  cameras: {}", cams.join(", "));
    if let Some(v) = s.view_space {
        println!("  view space: {}D", v.dimensions());
    }
    for p in &s.paths {
        println!("  path `{}`: {} keys", p.name, p.keys.len());
    }
    if s.is_static() {
        println!("  static scene: one time sample, no temporal decomposition");
    } else {
        let a = s.animation;
        println!(
            "  animated over [{}, {}] s at {} frames/s",
            a.start, a.end, a.fps
        );
    }
    if !s.has_specular() {
        println!("  no glossy or mirror surfaces: no specular rays are traced");
    }
}

#[derive(clap::Args)]
struct PlanArgs {
    scene: PathBuf,
    /// Quality in [0, 1]: the fitness every cell and interval must reach.
    #[arg(long)]
    quality: f32,
    /// Write the plan here as JSON.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Side of the square id-images (default from the quality: 64 at 0 to 256 at 1).
    #[arg(long)]
    resolution: Option<u32>,
    /// One master time list for every view (the paper's choice).
    #[arg(long)]
    master_list: bool,
    /// What a view-space cell's fitness measures.
    #[arg(long, value_parser = cli::choice::<ViewFitness>(), default_value_t = ViewFitness::Ids)]
    view_fitness: ViewFitness,
    #[arg(long, value_parser = cli::choice::<Backend>(), default_value_t = Backend::default_available())]
    backend: Backend,
    /// Replace the scene's view space by the segment `x,y,z:x,y,z`.
    #[arg(long, value_parser = rangewalk::scene::parse_segment, allow_hyphen_values = true)]
    view_segment: Option<rangewalk::scene::ViewSpace>,
}

/// `rangewalk plan`: the plan, the fitness behind each choice and each
/// step's time on stdout; the JSON in `--out`.
fn plan(args: PlanArgs) -> Result<()> {
    use rangewalk::plan::{self, PlanOptions};
    use rangewalk::scene::ViewSpace;
    let quality = Quality::new(args.quality).context("--quality")?;
    if let Some(n) = args.resolution.filter(|n| !plan::RESOLUTIONS.contains(n)) {
        bail!(
            "--resolution {n} is outside [{}, {}]",
            plan::RESOLUTIONS.start(),
            plan::RESOLUTIONS.end()
        );
    }
    if let Some(out) = &args.out {
        image::check_output("--out", out, image::OutputKind::Json)?;
    }
    let mut s = load(&args.scene)?;
    if let Some(space) = args.view_segment {
        s.view_space = Some(space);
    }
    let mut engine = engine_at_start(&s, args.backend)?;
    let options = PlanOptions {
        quality,
        resolution: args.resolution,
        master_list: args.master_list,
        view_fitness: args.view_fitness,
    };
    let p = plan::make(&s, engine.as_mut(), &options)?;
    let list = |ts: &[f32]| {
        ts.iter()
            .map(|t| t.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    println!(
        "{}: quality {}, id-images {}x{}, backend {}, view space {}",
        s.source.display(),
        p.quality,
        p.resolution,
        p.resolution,
        args.backend,
        match s.view_space {
            Some(ViewSpace::Segment { a, b }) => format!("segment {a} to {b}"),
            Some(ViewSpace::Rectangle { min, max }) => format!("rectangle {min} to {max}"),
            Some(ViewSpace::Box { min, max }) => format!("box {min} to {max}"),
            None => "none".into(),
        }
    );
    for l in &p.lights {
        println!("  light camera: {l}");
    }
    println!(
        "light times ({}): {}",
        p.light_times.len(),
        list(&p.light_times)
    );
    if !p.cells.is_empty() {
        println!(
            "view-space cells, fitness by {}: {}",
            p.view_fitness,
            p.view_fitness.get_documentation().unwrap_or_default()
        );
    }
    for c in &p.cells {
        println!(
            "  cell depth {} views {:?}: {}",
            c.depth,
            c.corners,
            match (c.fitness, c.split) {
                (None, _) => "not tested".to_string(),
                (Some(f), true) => format!("fitness {f:.4} < {}: split", p.quality),
                (Some(f), false) => format!("fitness {f:.4}: kept"),
            }
        );
    }
    println!("base views ({}):", p.views.len());
    for (i, v) in p.views.iter().enumerate() {
        println!(
            "  view {i} at {}: {} times: {}",
            v.position,
            v.times.len(),
            list(&v.times)
        );
    }
    for t in &p.intervals {
        let verdict = if t.split {
            "split"
        } else if t.fitness < p.quality {
            "one frame apart, kept"
        } else {
            "coherent"
        };
        let whose = t.view.map_or("lights".to_string(), |v| format!("view {v}"));
        println!(
            "  {whose} [{}, {}]: fitness {:.4}: {verdict}",
            t.t0, t.t1, t.fitness
        );
    }
    for why in &p.skipped {
        println!("skipped: {why}");
    }
    for st in &p.steps {
        println!(
            "step {}: {:.3} s, {} id-images",
            st.name, st.seconds, st.id_images
        );
    }
    if let Some(out) = &args.out {
        p.save(out)?;
        println!("plan written to {}", out.display());
    }
    Ok(())
}

#[derive(clap::Args)]
struct BakeArgs {
    #[arg(required_unless_present_any = ["status", "finish"])]
    scene: Option<PathBuf>,
    /// Quality in [0, 1] of every stage: views, times, radiosity.
    #[arg(long, required_unless_present_any = ["status", "finish"])]
    quality: Option<f32>,
    /// Bake directory: created, or resumed if it holds an unfinished bake of
    /// the same scene and settings.
    #[arg(long, required_unless_present_any = ["status", "finish"])]
    out: Option<PathBuf>,
    #[command(flatten)]
    options: BakeOptions,
    /// Bake only every n-th image from the i-th (`i/n`, i from 0), so that
    /// n machines can share one bake directory.
    #[arg(long, default_value = "0/1")]
    shard: Shard,
    /// Take the shard from the Slurm array task this runs in
    /// (SLURM_ARRAY_TASK_ID of SLURM_ARRAY_TASK_COUNT).
    #[arg(long, conflicts_with = "shard")]
    shard_from_env: bool,
    /// Only plan and solve radiosity, rendering no image: the first job of a
    /// distributed bake, before the shards.
    #[arg(long, conflicts_with_all = ["shard", "shard_from_env"])]
    prepare: bool,
    /// Count the done images of the bake in DIR and name the runs working
    /// on it (they may run elsewhere), and exit. Takes no lock.
    #[arg(long, value_name = "DIR", exclusive = true)]
    status: Option<PathBuf>,
    /// Read every image of the bake in DIR back against its checksum and
    /// mark the bake complete; fails, naming them, if any is missing or
    /// damaged, and is refused while a run renders. The last job of a
    /// distributed bake.
    #[arg(long, value_name = "DIR", exclusive = true)]
    finish: Option<PathBuf>,
}

/// `--noise`: a target, or none (`off`). Named apart from `Option` so that
/// clap takes it as the value of an argument that always has one.
type NoiseOption = Option<f32>;

/// The settings of a bake besides its scene, quality and directory, shared
/// by `bake` and `slurm` (which passes them on to the jobs).
#[derive(clap::Args)]
struct BakeOptions {
    /// Side of the square base images (default: from --frame-size and the
    /// scene's narrowest field of view).
    #[arg(long)]
    size: Option<u32>,
    /// Size of the frames that will be synthesized, `<W>x<H>`: sets the
    /// default --size so that no base pixel is coarser than a frame pixel.
    #[arg(long, default_value = bake::DEFAULT_FRAME_SIZE, value_parser = image::parse_size)]
    frame_size: (u32, u32),
    /// Samples per base-image pixel; with --noise, the least a pixel takes.
    #[arg(long, default_value_t = bake::DEFAULT_SPP)]
    spp: u32,
    /// Relative standard error of a base pixel's mean luminance at which it
    /// stops taking samples (0.02: 2 %), or `off`: every pixel takes --spp
    /// [default: 0.02].
    #[arg(long, value_name = "REL|off", value_parser = bake::sampling::parse_noise, allow_negative_numbers = true)]
    noise: Option<NoiseOption>,
    /// Most samples a base pixel takes with --noise (default: 16 × --spp).
    #[arg(long)]
    max_spp: Option<u32>,
    #[arg(long, value_parser = cli::choice::<BaseProjection>(), default_value_t = BaseProjection::Sphere)]
    projection: BaseProjection,
    /// Diffuse indirect light: radiosity records (the paper's multipass
    /// renderer) or traced.
    #[arg(long, value_parser = cli::choice::<IndirectSource>(), default_value_t = IndirectSource::Radiosity)]
    indirect: IndirectSource,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    #[arg(long, value_parser = cli::choice::<Backend>(), default_value_t = Backend::default_available())]
    backend: Backend,
    /// Longest path, counted as Mitsuba's `max_depth`; unlimited by default.
    #[arg(long)]
    max_depth: Option<u32>,
    /// Side of the planner's id-images (default from the quality).
    #[arg(long)]
    resolution: Option<u32>,
    /// One master time list for every view (the paper's choice).
    #[arg(long)]
    master_list: bool,
    /// What a view-space cell's fitness measures.
    #[arg(long, value_parser = cli::choice::<ViewFitness>(), default_value_t = ViewFitness::Ids)]
    view_fitness: ViewFitness,
    /// Keep every pixel of each base's projection, not only the window
    /// that may see the scene (the rest sees only sky, which frames trace).
    #[arg(long)]
    whole_bases: bool,
}

impl BakeOptions {
    /// The settings these options give for `s`, and a line saying how the
    /// image size was chosen.
    fn settings(
        &self,
        s: &Scene,
        quality: Quality,
    ) -> Result<(bake::Settings, bake::Sampling, String)> {
        let (size, why) = bake::size::resolve(s, self.size, self.projection, self.frame_size)?;
        let settings = bake::Settings {
            quality: quality.get(),
            size,
            spp: self.spp,
            projection: self.projection,
            indirect: self.indirect,
            seed: self.seed,
            backend: self.backend,
            max_depth: self.max_depth,
            planning: bake::Planning {
                resolution: self.resolution,
                master_list: self.master_list,
                view_fitness: self.view_fitness,
                whole: self.whole_bases,
            },
        };
        let sampling = bake::Sampling {
            noise: self.noise.unwrap_or(Some(bake::sampling::DEFAULT_NOISE)),
            max_spp: self.max_spp,
        };
        sampling.check(self.spp)?;
        Ok((settings, sampling, why))
    }

    /// The same options as `rangewalk bake` arguments, every one spelled
    /// out so that the jobs do not depend on defaults.
    fn words(&self) -> Vec<String> {
        let mut w: Vec<String> = Vec::new();
        let mut push = |k: &str, v: String| {
            w.push(k.into());
            w.push(v);
        };
        if let Some(n) = self.size {
            push("--size", n.to_string());
        }
        push(
            "--frame-size",
            format!("{}x{}", self.frame_size.0, self.frame_size.1),
        );
        push("--spp", self.spp.to_string());
        let noise = self.noise.unwrap_or(Some(bake::sampling::DEFAULT_NOISE));
        push("--noise", noise.map_or("off".into(), |n| n.to_string()));
        if let Some(m) = self.max_spp {
            push("--max-spp", m.to_string());
        }
        push("--projection", self.projection.to_string());
        push("--indirect", self.indirect.to_string());
        push("--seed", self.seed.to_string());
        push("--backend", self.backend.to_string());
        if let Some(d) = self.max_depth {
            push("--max-depth", d.to_string());
        }
        if let Some(r) = self.resolution {
            push("--resolution", r.to_string());
        }
        push("--view-fitness", self.view_fitness.to_string());
        if self.master_list {
            w.push("--master-list".into());
        }
        if self.whole_bases {
            w.push("--whole-bases".into());
        }
        w
    }
}

/// `rangewalk bake`: plan (when starting), radiosity (once), then this
/// shard's missing base images, with progress and a summary.
fn bake_command(args: BakeArgs) -> Result<()> {
    use rangewalk::plan::{self, PlanOptions};
    if let Some(dir) = &args.status {
        return bake_status(dir);
    }
    if let Some(dir) = &args.finish {
        return bake_finish(dir);
    }
    let (Some(scene), Some(quality), Some(out)) = (&args.scene, args.quality, &args.out) else {
        bail!("bake needs a scene, --quality and --out");
    };
    let quality = Quality::new(quality).context("--quality")?;
    image::check_output_dir("--out", out)?;
    let shard = if args.shard_from_env {
        bake::slurm::shard_from_env()?
    } else {
        args.shard
    };
    let s = load(scene)?;
    let (settings, sampling, why) = args.options.settings(&s, quality)?;
    println!("{why}");
    let mut engine = engine_at_start(&s, settings.backend)?;
    let options = PlanOptions {
        quality,
        resolution: args.options.resolution,
        master_list: args.options.master_list,
        view_fitness: args.options.view_fitness,
    };
    let plan = |e: &mut dyn InstancedEngine| plan::make(&s, e, &options);
    let summary = if args.prepare {
        bake::prepare(&s, out, &settings, &sampling, engine.as_mut(), plan)?
    } else {
        bake::run_observed(
            &s,
            out,
            &settings,
            &sampling,
            shard,
            engine.as_mut(),
            plan,
            &mut |_| true,
        )?
    };
    if summary.removed > 0 {
        println!(
            "removed {} temporary files left by a stopped run",
            summary.removed
        );
    }
    let manifest = bake::Manifest::read(out)?;
    let p = &manifest.plan;
    match summary.plan_seconds {
        Some(t) => println!(
            "plan: {} views, {} images, {t:.3} s",
            p.views.len(),
            manifest.images.len()
        ),
        None => println!(
            "plan: {} views, {} images (from the bake's manifest)",
            p.views.len(),
            manifest.images.len()
        ),
    }
    for (i, v) in p.views.iter().enumerate() {
        let times: Vec<String> = v.times.iter().map(|t| t.to_string()).collect();
        println!("  view {i} at {}: times {}", v.position, times.join(", "));
    }
    for why in &p.skipped {
        println!("  skipped: {why}");
    }
    println!(
        "{}",
        bake::window::describe(&manifest.windows, manifest.settings.size)
    );
    match (settings.indirect, summary.radiosity_seconds) {
        (IndirectSource::Path, _) => println!("radiosity skipped: indirect light is traced"),
        (_, Some(t)) => println!("radiosity: solved in {t:.3} s"),
        (_, None) if summary.rendered > 0 || args.prepare => println!(
            "radiosity: reused from {}",
            out.join(bake::manifest::RADIOSITY).display()
        ),
        (_, None) => {}
    }
    if !s.has_specular() {
        println!("specular rays skipped: no glossy or mirror surfaces");
    }
    if args.prepare {
        println!(
            "prepared {}: {} of {} images finished; bake the rest with --shard i/n or --shard-from-env",
            out.display(),
            summary.finished,
            summary.total
        );
        return Ok(());
    }
    let shard = if shard.count > 1 {
        format!(" (shard {}/{})", shard.index, shard.count)
    } else {
        String::new()
    };
    println!(
        "images{shard}: {} rendered, {} already done; {} of {} in the bake finished",
        summary.rendered, summary.reused, summary.finished, summary.total
    );
    if summary.rendered > 0 {
        let t = summary.render_seconds;
        println!(
            "  {t:.3} s, {:.3} M samples/s, {:.2} M shaded rays/s, backend {}",
            summary.samples as f64 / t / 1e6,
            summary.rays as f64 / t / 1e6,
            settings.backend
        );
    }
    if let Some(noise) = &summary.noise {
        println!("  noise ({}): {noise}", sampling.describe());
    }
    if summary.complete {
        println!("bake complete: {}", out.display());
    } else {
        println!(
            "bake not complete: {} images missing; run the other shards (or this command again)",
            summary.total - summary.finished
        );
    }
    Ok(())
}

/// The first few of `files`, for a message.
fn some_of(files: &[String]) -> String {
    const SHOWN: usize = 8;
    let mut s = files
        .iter()
        .take(SHOWN)
        .cloned()
        .collect::<Vec<_>>()
        .join(", ");
    if files.len() > SHOWN {
        s += &format!(" and {} more", files.len() - SHOWN);
    }
    s
}

/// `rangewalk bake --status`: how many images are done, who is working
/// on them, and what to do next. Takes no lock: it watches a bake that
/// may run anywhere.
fn bake_status(dir: &Path) -> Result<()> {
    let st = bake::status::status(dir)?;
    let radiosity = match st.radiosity {
        None => "",
        Some(true) => "; radiosity solved",
        Some(false) => "; radiosity not solved yet",
    };
    let missing = st.total - st.done;
    let verdict = if st.complete {
        "bake complete".to_string()
    } else if st.sealed {
        format!(
            "not complete: {missing} of its images went missing after the bake was completed; run the bake command again to render them again"
        )
    } else if missing == 0 && st.running.is_empty() {
        format!(
            "not complete: every image is done but not checked yet; run `rangewalk bake --finish {}` (or the bake command again)",
            dir.display()
        )
    } else {
        "not complete".to_string()
    };
    println!(
        "{}: {} of {} images done ({:.0}%){radiosity}; {verdict}",
        dir.display(),
        st.done,
        st.total,
        100.0 * st.done as f64 / st.total.max(1) as f64,
    );
    if !st.missing.is_empty() {
        println!("  to do: {}", some_of(&st.missing));
    }
    if let Some(noise) = &st.noise {
        println!("  noise of the done images: {noise}");
    }
    for h in &st.running {
        println!("  running: {h}");
    }
    Ok(())
}

/// `rangewalk bake --finish`: every image checked, the bake sealed.
fn bake_finish(dir: &Path) -> Result<()> {
    let st = bake::status::finish(dir)?;
    if st.removed > 0 {
        println!(
            "removed {} temporary files left by a stopped run",
            st.removed
        );
    }
    if !st.missing.is_empty() {
        bail!(
            "{}: {} of {} images missing or damaged: {}; run their shards again (or the same bake or slurm command), then finish again",
            dir.display(),
            st.missing.len(),
            st.total,
            some_of(&st.missing)
        );
    }
    println!(
        "bake complete: {}: {} images read back against their checksums",
        dir.display(),
        st.total
    );
    Ok(())
}

#[derive(clap::Args)]
struct SlurmArgs {
    scene: PathBuf,
    /// Quality in [0, 1] of every stage: views, times, radiosity.
    #[arg(long)]
    quality: f32,
    /// Bake directory, on a filesystem every node sees; the job scripts go
    /// into its `slurm/` folder.
    #[arg(long)]
    out: PathBuf,
    /// Tasks of the bake array (each renders every n-th image).
    #[arg(long)]
    tasks: u32,
    #[command(flatten)]
    options: BakeOptions,
    /// Slurm partition of every job.
    #[arg(long)]
    partition: Option<String>,
    /// Slurm time limit of every job (minutes, MM:SS, HH:MM:SS or D-HH:MM:SS).
    #[arg(long)]
    time_limit: Option<String>,
    /// CPUs of every job; the renderer uses that many threads.
    #[arg(long)]
    cpus_per_task: Option<u32>,
    /// Submit the jobs with sbatch and print their ids.
    #[arg(long)]
    submit: bool,
}

/// `rangewalk slurm`: the job scripts of a distributed bake, submitted or
/// with the commands that submit them.
fn slurm_command(a: SlurmArgs) -> Result<()> {
    use bake::slurm;
    let quality = Quality::new(a.quality).context("--quality")?;
    image::check_output_dir("--out", &a.out)?;
    let s = load(&a.scene)?;
    let (settings, sampling, why) = a.options.settings(&s, quality)?;
    if a.tasks == 0 {
        bail!("--tasks must be at least 1");
    }
    bake::check_resumable(&s, &a.out, &settings, &sampling)?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let absolute =
        |p: &Path| std::fs::canonicalize(p).with_context(|| format!("resolving {}", p.display()));
    let (dir, scene) = (absolute(&a.out)?, absolute(&a.scene)?);
    let program = absolute(&std::env::current_exe().context("finding the rangewalk binary")?)?;
    let mut words = vec![
        scene.to_string_lossy().into_owned(),
        "--quality".into(),
        quality.get().to_string(),
        "--out".into(),
        dir.to_string_lossy().into_owned(),
    ];
    words.extend(a.options.words());
    let job = slurm::JobOptions {
        partition: a.partition,
        time_limit: a.time_limit,
        cpus_per_task: a.cpus_per_task,
    };
    let scripts = slurm::write_scripts(&dir, &program, &words, a.tasks, &job)?;
    println!("{why}");
    println!(
        "job scripts for {} tasks in {}:",
        a.tasks,
        dir.join(bake::SLURM_DIR).display()
    );
    for p in [&scripts.prepare, &scripts.bake, &scripts.finish] {
        println!("  {}", p.display());
    }
    if a.submit {
        let ids = slurm::submit(&scripts)?;
        println!("submitted {} as job {}", slurm::PREPARE, ids.prepare);
        println!(
            "submitted {} as job {} (tasks 0-{}, after job {})",
            slurm::BAKE,
            ids.bake,
            a.tasks - 1,
            ids.prepare
        );
        println!(
            "submitted {} as job {} (after job {})",
            slurm::FINISH,
            ids.finish,
            ids.bake
        );
        println!(
            "watch: squeue -j {},{},{}; rangewalk bake --status {}",
            ids.prepare,
            ids.bake,
            ids.finish,
            dir.display()
        );
    } else {
        println!("submit them with:\n{}", slurm::submit_commands(&scripts));
    }
    Ok(())
}
