//! Image error against references and the experiments that reproduce the
//! paper's tables.

use anyhow::Result;

pub mod experiment;
pub mod flip;
pub mod metrics;
pub mod motion;
pub mod plot;
pub mod reference;
pub mod report;
mod staging;
pub mod summary;
pub mod synthesis;
pub mod views;
pub mod walkcheck;
pub mod walkthrough;

/// The experiments of `rangewalk experiment`.
#[derive(clap::Subcommand, Clone, Debug)]
pub enum Experiment {
    /// Indirect light from radiosity records in a multipass renderer against
    /// path-traced references, per quality, over the animation (paper
    /// Tables 1 and 2); writes table.md, frames.csv, convergence.csv, plots
    /// and previews.
    Indirect(experiment::IndirectArgs),
    /// View reconstruction between base views along a 1D view subspace,
    /// per quality and fill mode, with the resampling error alone (paper
    /// Table 3); writes table.md, qualities.csv, plots and image strips.
    Views(views::ViewsArgs),
    /// Object motion interpolated in time from base images at one fixed
    /// view, per quality and time interpolation (linear, motion
    /// compensated, re-shaded), every frame against a reference (paper
    /// Table 4); writes table.md, qualities.csv, frames.csv, plots and
    /// image strips.
    Motion(motion::MotionArgs),
    /// The whole framework (plan, simplification and radiosity, bake,
    /// synthesis) on a walk path, every phase timed, every frame against a
    /// path-traced frame, with the path tracer's time to the same error and
    /// the frames at which the bake pays (paper Table 5); writes table.md,
    /// qualities.csv, frames.csv, convergence.csv, plots and image strips.
    Walkthrough(walkthrough::WalkthroughArgs),
}

/// One line per quality and time interpolation of a sequence experiment.
fn sequence_summary(qualities: &[synthesis::SequenceQuality]) {
    for q in qualities {
        for m in &q.modes {
            println!(
                "q = {}, {}: {} base image(s), {:.3} s synthesis + {:.3} s loading for {} frames, mean LRMS {:.4}",
                q.quality,
                synthesis::mode_name(m.mode),
                q.baked_images,
                m.synth_s(),
                m.load_s(),
                m.frames.len(),
                m.mean_lrms()
            );
        }
    }
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
        Experiment::Views(args) => {
            let r = views::run(&args)?;
            for q in &r.qualities {
                let both = |runs: &[views::FillRun]| {
                    runs.iter()
                        .find(|f| f.fill == crate::synth::Fill::Both)
                        .map_or(f64::NAN, |f| f.frame.error.lrms)
                };
                println!(
                    "q = {}: {} views, bases {:.3} apart: LRMS {:.4} (fill both), resampled {:.4}",
                    q.quality,
                    q.plan.views.len(),
                    q.spacing(),
                    both(&q.synthesized),
                    both(&q.resampled)
                );
            }
            println!("report written to {}", r.out.join("table.md").display());
        }
        Experiment::Motion(args) => {
            let r = motion::run(&args)?;
            sequence_summary(&r.qualities);
            println!("report written to {}", r.out.join("table.md").display());
        }
        Experiment::Walkthrough(args) => {
            let r = walkthrough::run(&args)?;
            sequence_summary(&r.qualities);
            println!("report written to {}", r.out.join("table.md").display());
        }
    }
    Ok(())
}
