//! Synthesizes frames of the synthesis benchmark (the Cornell box's walk
//! at t = 0.5, 512², bases at t = 0) from a bake the benchmark kept with
//! `RANGEWALK_BENCH_BAKES`, and prints a digest of the last frame and the
//! wall time a frame. Under `valgrind --tool=callgrind` the difference in
//! instructions between two frame counts is the work of the frames alone,
//! a measure that, unlike time on a shared machine, does not vary from
//! run to run:
//!
//! ```sh
//! cargo run --release --example synth_frames -- <bake-dir> <views> <frames> [nearest|average]
//! ```

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use rangewalk::bake::Bake;
use rangewalk::scene::Scene;
use rangewalk::synth::{Blend, Filter, Options, Synthesizer, TimeInterp, DEFAULT_BUDGET};

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [dir, views, frames, rest @ ..] = &args[..] else {
        bail!("usage: synth_frames <bake-dir> <views> <frames> [nearest|average]");
    };
    let views: usize = views.parse().context("views")?;
    let frames: usize = frames.parse().context("frames")?;
    let blend = match rest.first().map(String::as_str) {
        None | Some("nearest") => Blend::Nearest,
        Some("average") => Blend::Average,
        Some(other) => bail!("blend {other:?} is neither nearest nor average"),
    };
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml");
    let scene = Scene::load(&path)?;
    let camera = scene
        .path("walk")
        .context("the walk path")?
        .at(0.5)
        .perspective(512, 512)?;
    let bake = Bake::open(&PathBuf::from(dir), &scene)?;
    let mut synth = Synthesizer::new(&scene, &bake, DEFAULT_BUDGET);
    let options = Options {
        bases: views,
        time_interp: TimeInterp::Motion,
        supersample: 1,
        filter: Filter::Cover,
        blend,
        ..Options::default()
    };
    // The first frame reads the bases; the rest are timed.
    synth.frame(&camera, 0.0, &options)?;
    let start = std::time::Instant::now();
    let mut summary = String::new();
    for _ in 0..frames {
        let (frame, stats) = synth.frame(&camera, 0.0, &options)?;
        let sum: f64 = frame.radiance.iter().map(|r| r.element_sum() as f64).sum();
        summary = format!("radiance sum {sum:.6}, {} holes", stats.holes);
        synth.recycle(frame);
    }
    let per = start.elapsed().as_secs_f64() * 1e3 / frames.max(1) as f64;
    println!("{summary}; {per:.2} ms a frame");
    Ok(())
}
