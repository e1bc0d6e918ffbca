//! `rangewalk bake`: plan, radiosity and this shard's base images, resumed
//! where an earlier run stopped.

use std::path::PathBuf;

use anyhow::{bail, Result};
use rangewalk::accel::InstancedEngine;
use rangewalk::bake::{self, IndirectSource, Shard};
use rangewalk::image;
use rangewalk::plan::{self, PlanOptions};
use rangewalk::quality::Quality;

use super::bake_options::BakeOptions;
use super::bake_status;
use super::{engine_at_start, load};

/// `rangewalk bake`.
#[derive(clap::Args)]
pub struct BakeArgs {
    #[arg(required_unless_present_any = ["status", "finish"])]
    scene: Option<PathBuf>,
    /// Quality in [0, 1] of every stage: views, times, radiosity.
    #[arg(long, required_unless_present_any = ["status", "finish"])]
    quality: Option<Quality>,
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

/// `rangewalk bake`: plan (when starting), radiosity (once), then this
/// shard's missing base images, with progress and a summary.
pub fn run(args: BakeArgs) -> Result<()> {
    if let Some(dir) = &args.status {
        return bake_status::status(dir);
    }
    if let Some(dir) = &args.finish {
        return bake_status::finish(dir);
    }
    let (Some(scene), Some(quality), Some(out)) = (&args.scene, args.quality, &args.out) else {
        bail!("bake needs a scene, --quality and --out");
    };
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
