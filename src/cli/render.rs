//! `rangewalk render`: one frame path traced, or multipass with radiosity.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use rangewalk::accel::{self, Backend, InstancedEngine};
use rangewalk::bake::IndirectSource;
use rangewalk::camera::Camera;
use rangewalk::image::{self, RangeImage};
use rangewalk::quality::Quality;
use rangewalk::radiosity::lookup::IrradianceCache;
use rangewalk::radiosity::temporal::TimeSeries;
use rangewalk::radiosity::{self, store as radiosity_store, Simplified};
use rangewalk::render::{self, multipass, RenderSettings, RenderStats};
use rangewalk::scene::Scene;

use super::camera::CameraArgs;
use super::{choice, load};

/// `rangewalk render`.
#[derive(clap::Args)]
pub struct RenderArgs {
    scene: PathBuf,
    #[command(flatten)]
    camera: CameraArgs,
    /// Samples per pixel.
    #[arg(long, default_value_t = 64)]
    spp: u32,
    /// Output range image (OpenEXR: radiance, distance, ids, normals).
    #[arg(long)]
    out: PathBuf,
    #[arg(long, value_parser = choice::<Backend>(), default_value_t = Backend::default_available())]
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
}

pub fn run(args: RenderArgs) -> Result<()> {
    let RenderArgs {
        scene,
        camera: view,
        spp,
        out,
        backend,
        seed,
        max_depth,
        preview,
        hdr,
        exposure,
        indirect,
    } = args;
    if spp == 0 {
        bail!("--spp must be at least 1");
    }
    indirect.check()?;
    image::check_output("--out", &out, image::OutputKind::Exr)?;
    if let Some(dir) = indirect
        .bake
        .as_ref()
        .filter(|d| !d.join(radiosity_store::MANIFEST).exists())
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
        IndirectSource::Path => render::render(&s, engine.as_ref(), &camera, view.time, &settings)?,
        IndirectSource::Radiosity | IndirectSource::Gather => render_multipass(
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
            IndirectSource::Path => "path traced",
            IndirectSource::Radiosity => "multipass with radiosity indirect",
            IndirectSource::Gather => "multipass with radiosity indirect gathered",
        },
        backend,
        stats.seconds,
        build_s,
        stats.samples as f64 / stats.seconds / 1e6,
        stats.rays as f64 / stats.seconds / 1e6,
    );
    Ok(())
}

#[derive(clap::Args)]
pub struct IndirectArgs {
    /// Where diffuse indirect light comes from: traced paths, or radiosity
    /// records looked up (or gathered) by the multipass renderer.
    #[arg(long, value_parser = choice::<IndirectSource>(), default_value_t = IndirectSource::Path)]
    indirect: IndirectSource,
    /// Quality in [0, 1] of the radiosity stages (with `--indirect
    /// radiosity` or `gather`): 0.5 if not given, or the bake's.
    #[arg(long)]
    quality: Option<Quality>,
    /// Bake directory: used if it exists, written if not (with
    /// `--indirect radiosity` or `gather`).
    #[arg(long)]
    bake: Option<PathBuf>,
}

impl IndirectArgs {
    fn check(&self) -> Result<()> {
        if self.indirect == IndirectSource::Path {
            if self.bake.is_some() {
                bail!("--bake applies to --indirect radiosity or gather only");
            }
            if self.quality.is_some() {
                bail!("--quality applies to --indirect radiosity or gather only");
            }
        }
        Ok(())
    }
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
    let q = args.quality;
    let (simplified, series) = match &args.bake {
        Some(dir) if dir.join(radiosity_store::MANIFEST).exists() => {
            load_bake(s, dir, q).context("--bake")?
        }
        bake_dir => {
            let q = q.unwrap_or(Quality::DEFAULT);
            let (simplified, series) = radiosity::simplify_and_decompose(s, engine, q)?;
            if let Some(dir) = bake_dir {
                radiosity_store::save(dir, s, &simplified, &series)?;
                eprintln!("bake written to {}", dir.display());
            }
            (simplified, series)
        }
    };
    engine
        .set_transforms(&s.at(time))
        .with_context(|| format!("posing the scene at t = {time}"))?;
    let cache = IrradianceCache::new(&simplified, &series.indirect_at(time))?;
    let indirect = match args.indirect {
        IndirectSource::Gather => multipass::Indirect::Gathered(&cache),
        _ => multipass::Indirect::Records(&cache),
    };
    let out = multipass::render_layers(
        s,
        &*engine,
        camera,
        time,
        settings,
        indirect,
        None,
        render::Progress::Tiles,
    )?;
    Ok((out.image, out.stats))
}

/// A bake made for this scene (at quality `q`, if given).
fn load_bake(s: &Scene, dir: &Path, q: Option<Quality>) -> Result<(Simplified, TimeSeries)> {
    let (simplified, series, info) = radiosity_store::load_for(dir, s, q)?;
    eprintln!(
        "using the bake in {} (quality {}, {} solutions)",
        dir.display(),
        info.quality,
        series.solutions.len()
    );
    Ok((simplified, series))
}
