//! Image error against references and the experiments that reproduce the
//! paper's tables.

use anyhow::Result;

pub mod experiment;
pub mod flip;
pub mod metrics;
pub mod plot;
pub mod reference;
pub mod report;
mod staging;
pub mod summary;

/// The experiments of `rangewalk experiment`.
#[derive(clap::Subcommand, Clone, Debug)]
pub enum Experiment {
    /// Indirect light from radiosity records in a multipass renderer against
    /// path-traced references, per quality, over the animation (paper
    /// Tables 1 and 2); writes table.md, frames.csv, convergence.csv, plots
    /// and previews.
    Indirect(experiment::IndirectArgs),
}

/// Runs one experiment and says where its report is.
pub fn run(experiment: Experiment) -> Result<()> {
    match experiment {
        Experiment::Indirect(args) => {
            let r = experiment::run_indirect(&args)?;
            for q in &r.qualities {
                let lrms: f64 =
                    q.frames.iter().map(|f| f.error.lrms).sum::<f64>() / q.frames.len() as f64;
                println!(
                    "q = {}: {} solve(s), {:.3} s in all, mean LRMS {:.4}",
                    q.quality,
                    q.solves.len(),
                    q.total_s(),
                    lrms
                );
            }
            println!("report written to {}", r.out.join("table.md").display());
        }
    }
    Ok(())
}
