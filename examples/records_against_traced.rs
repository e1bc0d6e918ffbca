//! The radiosity records against a traced bounce, in one scene: renders a
//! camera of it with the multipass renderer twice, once with the records'
//! indirect irradiance and once with one traced diffuse bounce in its
//! place (the comparison `tests/multipass.rs` checks the studio with), and
//! prints the mean luminance of both images and of their indirect layers,
//! and of both images over the pixels darker than the traced one's mean.
//! Noise aside, the layers differ only by the records' error, so a
//! change to a scene that moves one and not the other points at the solver.
//!
//! ```sh
//! cargo run --release --example records_against_traced -- <scene.toml> \
//!     [--quality 0.3] [--whole] [--size 96] [--spp 128] [--camera main] [--time 0]
//! ```
//!
//! `--whole` solves on every input triangle (`Simplified::whole`) instead
//! of the simplification's patches.

use anyhow::{bail, Context, Result};
use glam::Vec3;
use rangewalk::accel::{self, Backend};
use rangewalk::eval::metrics::luminance;
use rangewalk::quality::Quality;
use rangewalk::radiosity::lookup::IrradianceCache;
use rangewalk::radiosity::{simplify, solve, Simplified};
use rangewalk::render::{self, multipass, RenderSettings};
use rangewalk::scene::Scene;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((path, rest)) = args.split_first() else {
        bail!("usage: records_against_traced <scene.toml> [--quality q] [--whole] [--size n] [--spp n] [--camera name] [--time t]");
    };
    let (mut quality, mut whole, mut size, mut spp) = (0.3f32, false, 96u32, 128u32);
    let (mut camera, mut time) = ("main".to_string(), 0.0f32);
    let mut it = rest.iter();
    while let Some(flag) = it.next() {
        if flag == "--whole" {
            whole = true;
            continue;
        }
        let v = it.next().with_context(|| format!("{flag} needs a value"))?;
        match flag.as_str() {
            "--quality" => quality = v.parse().context("--quality")?,
            "--size" => size = v.parse().context("--size")?,
            "--spp" => spp = v.parse().context("--spp")?,
            "--camera" => camera = v.clone(),
            "--time" => time = v.parse().context("--time")?,
            _ => bail!("unknown option {flag}"),
        }
    }
    let scene = Scene::load(path)?;
    let q = Quality::new(quality)?;
    let mut engine = accel::build(
        Backend::default_available(),
        &scene.geometry(),
        &scene.at(time),
    )?;
    let simplified = if whole {
        Simplified::whole(&scene)
    } else {
        let s = simplify(&scene, engine.as_mut(), q)?;
        engine.set_transforms(&scene.at(time))?;
        s
    };
    let solution = solve(&scene, &simplified, engine.as_ref(), time, q)?;
    println!("{:?}", solution.stats);
    let cache = IrradianceCache::new(&simplified, &solution.indirect)?;
    let cam = scene.camera(&camera)?.perspective(size, size)?;
    let settings = RenderSettings {
        spp,
        max_depth: None,
        seed: 3,
    };
    let mean = |v: &[Vec3]| v.iter().map(|&c| luminance(c)).sum::<f64>() / v.len() as f64;
    let mut means = Vec::new();
    let mut images = Vec::new();
    for indirect in [
        multipass::Indirect::Records(&cache),
        multipass::Indirect::Traced,
    ] {
        let out = multipass::render_layers(
            &scene,
            engine.as_ref(),
            &cam,
            time,
            &settings,
            indirect,
            None,
            render::Progress::Tiles,
        )?;
        images.push(
            out.image
                .radiance
                .iter()
                .map(|&c| luminance(c))
                .collect::<Vec<f64>>(),
        );
        means.push((mean(&out.image.radiance), mean(&out.indirect)));
    }
    // The pixels darker than the traced image's mean (away from the
    // lights), where the indirect light is most of what one sees.
    let [ref recs, ref traced_img] = images[..] else {
        unreachable!("two renders");
    };
    let cut = traced_img.iter().sum::<f64>() / traced_img.len() as f64;
    let dark: Vec<usize> = (0..traced_img.len())
        .filter(|&i| traced_img[i] < cut)
        .collect();
    let over = |v: &[f64]| dark.iter().map(|&i| v[i]).sum::<f64>() / dark.len().max(1) as f64;
    let (dark_records, dark_traced) = (over(recs), over(traced_img));
    let [(records, records_indirect), (traced, traced_indirect)] = means[..] else {
        unreachable!("two renders");
    };
    println!(
        "records: image {records:.4}, indirect layer {records_indirect:.4}; \
         traced bounce: image {traced:.4}, indirect layer {traced_indirect:.4}; \
         indirect layer {:+.1}%",
        100.0 * (records_indirect / traced_indirect - 1.0)
    );
    println!(
        "image {:+.1}%; the {} pixels darker than the traced image's mean: records {dark_records:.4}, \
         traced bounce {dark_traced:.4}, {:+.1}%",
        100.0 * (records / traced - 1.0),
        dark.len(),
        100.0 * (dark_records / dark_traced - 1.0)
    );
    Ok(())
}
