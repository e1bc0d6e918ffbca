//! `rangewalk plan`: base views and time lists from id-image fitness.

use std::path::PathBuf;

use anyhow::{bail, Result};
use rangewalk::accel::Backend;
use rangewalk::image;
use rangewalk::plan::{self, PlanOptions, ViewFitness};
use rangewalk::quality::Quality;
use rangewalk::scene::{self, ViewSpace};
use strum::EnumMessage;

use super::{choice, engine_at_start, load};

/// `rangewalk plan`.
#[derive(clap::Args)]
pub struct PlanArgs {
    scene: PathBuf,
    /// Quality in [0, 1]: the fitness every cell and interval must reach.
    #[arg(long)]
    quality: Quality,
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
    #[arg(long, value_parser = choice::<ViewFitness>(), default_value_t = ViewFitness::Ids)]
    view_fitness: ViewFitness,
    #[arg(long, value_parser = choice::<Backend>(), default_value_t = Backend::default_available())]
    backend: Backend,
    /// Replace the scene's view space by the segment `x,y,z:x,y,z`.
    #[arg(long, value_parser = scene::parse_segment, allow_hyphen_values = true)]
    view_segment: Option<ViewSpace>,
}

/// `rangewalk plan`: the plan, the fitness behind each choice and each
/// step's time on stdout; the JSON in `--out`.
pub fn run(args: PlanArgs) -> Result<()> {
    let quality = args.quality;
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
        } else if t.fitness < p.quality.get() {
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
