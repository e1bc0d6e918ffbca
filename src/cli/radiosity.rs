//! `rangewalk radiosity`: the object-space stages on their own, stored
//! for `render --indirect radiosity`.

use std::path::PathBuf;

use anyhow::Result;
use rangewalk::accel::Backend;
use rangewalk::image;
use rangewalk::quality::Quality;
use rangewalk::radiosity::temporal::{self, TimeSeries};
use rangewalk::radiosity::{self, store as radiosity_store, Simplified};
use rangewalk::scene::Scene;

use super::{choice, engine_at_start, load};

/// `rangewalk radiosity`.
#[derive(clap::Args)]
pub struct RadiosityArgs {
    scene: PathBuf,
    /// Quality in [0, 1]: finer simplification, more solves.
    #[arg(long, default_value_t = Quality::DEFAULT)]
    quality: Quality,
    /// Bake directory to write (replaced if it holds an earlier bake).
    #[arg(long)]
    out: PathBuf,
    #[arg(long, value_parser = choice::<Backend>(), default_value_t = Backend::default_available())]
    backend: Backend,
}

pub fn run(args: RadiosityArgs) -> Result<()> {
    let RadiosityArgs {
        scene,
        quality: q,
        out,
        backend,
    } = args;
    image::check_output_dir("--out", &out)?;
    let s = load(&scene)?;
    let mut engine = engine_at_start(&s, backend)?;
    let (simplified, series) = radiosity::simplify_and_decompose(&s, engine.as_mut(), q)?;
    radiosity_store::save(&out, &s, &simplified, &series)?;
    report_radiosity(&s, &simplified, &series);
    println!("bake written to {}", out.display());
    Ok(())
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
    let l = temporal::Thresholds::for_quality(series.quality);
    if d.static_scene {
        println!("temporal decomposition skipped: static scene, one solution");
    } else if d.intervals.is_empty() {
        println!("temporal decomposition skipped: the animation has no duration");
    } else {
        println!(
            "temporal decomposition: {} solves, depth {} of {} allowed, {:.3} s",
            d.solves, d.depth, d.max_depth, d.seconds
        );
        println!(
            "  split while relative RMS > {:.4} or fewer than {:.0}% of records unchanged",
            l.relative_rms,
            100.0 * l.unchanged_fraction
        );
        for i in &d.intervals {
            let incoherent = i.relative_rms > l.relative_rms || i.unchanged < l.unchanged_fraction;
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
