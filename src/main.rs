//! The `rangewalk` command line.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand, ValueEnum};

use rangewalk::accel::{self, Backend};
use rangewalk::camera::{Camera, Projection};
use rangewalk::image;
use rangewalk::render::{self, RenderSettings};
use rangewalk::scene::{Bsdf, Light, Scene};

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
    /// Path-trace a converged reference image of the scene at one time.
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
        #[arg(long, value_enum, default_value_t = Backend::default_available())]
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
    /// Measure a stage against path-traced references and write a report.
    Experiment {
        #[command(subcommand)]
        experiment: rangewalk::eval::Experiment,
    },
}

#[derive(clap::Args)]
struct ViewArgs {
    /// Scene time in seconds.
    #[arg(long, default_value_t = 0.0)]
    time: f32,
    /// Named camera of the scene.
    #[arg(long, default_value = "main")]
    camera: String,
    /// Image size, `<W>x<H>`.
    #[arg(long, default_value = "256x256", value_parser = parse_size)]
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

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let err = || format!("size `{s}` is not <W>x<H> with positive integers, e.g. 512x512");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(err)?;
    let (w, h) = (
        w.trim().parse::<u32>().map_err(|_| err())?,
        h.trim().parse::<u32>().map_err(|_| err())?,
    );
    if w == 0 || h == 0 || w > 32768 || h > 32768 {
        return Err(err());
    }
    Ok((w, h))
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
        if !self.time.is_finite() {
            bail!("--time {} is not a number", self.time);
        }
        let a = scene.animation;
        if !scene.is_static() && (self.time < a.start || self.time > a.end) {
            eprintln!(
                "note: --time {} lies outside the animation [{}, {}] s; objects hold their end poses",
                self.time, a.start, a.end
            );
        }
        Ok(())
    }
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
        } => {
            if spp == 0 {
                bail!("--spp must be at least 1");
            }
            let s = load(&scene)?;
            view.check_time(&s)?;
            let camera = view.camera(&s)?;
            let build = Instant::now();
            let engine = accel::build(backend, &s.geometry(), &s.at(view.time))
                .with_context(|| format!("building the {backend} ray engine"))?;
            let build_s = build.elapsed().as_secs_f64();
            let settings = RenderSettings {
                spp,
                max_depth,
                seed,
            };
            let (img, stats) = render::render(&s, engine.as_ref(), &camera, view.time, &settings)?;
            image::write_exr(&out, &img)?;
            if let Some(p) = preview {
                image::write_png_preview(&p, img.width, img.height, &img.radiance, exposure)?;
            }
            if let Some(p) = hdr {
                image::write_hdr(&p, img.width, img.height, &img.radiance)?;
            }
            println!(
                "{}: {}x{} at t = {} s, {} spp, backend {}: {:.3} s ({:.3} s build), {:.3} M samples/s, {:.2} M rays/s",
                out.display(),
                camera.width,
                camera.height,
                view.time,
                spp,
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
        Command::Experiment { experiment } => rangewalk::eval::run(experiment)?,
    }
    Ok(())
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
