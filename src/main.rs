//! The `rangewalk` command line: parsing and dispatch; each command lives
//! in `cli/<command>.rs`.

mod cli;

use std::process::ExitCode;

use anyhow::Result;
use clap::{Parser, Subcommand};

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
    Render(cli::render::RenderArgs),
    /// Write the scene at one time for another renderer.
    Export(cli::export::ExportArgs),
    /// Describe a scene and which stages it needs.
    Info(cli::info::InfoArgs),
    /// Simplify the scene, solve radiosity over the animation's time list
    /// and store the result in a bake directory.
    Radiosity(cli::radiosity::RadiosityArgs),
    /// Choose base views and their time lists from id-image fitness
    /// (paper §4.1-4.2) and write the plan as JSON.
    Plan(cli::plan::PlanArgs),
    /// Render the base range images of every (view, time) of the plan
    /// (paper §4.4) into a bake directory; resumes an unfinished bake.
    Bake(cli::bake::BakeArgs),
    /// Write (and with --submit, submit) Slurm job scripts that bake on a
    /// cluster: one job for the plan and radiosity, an array of bake tasks,
    /// one job that checks every image and marks the bake complete.
    Slurm(cli::slurm::SlurmArgs),
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
    Compare(cli::compare::CompareArgs),
    /// Measure a stage against path-traced references and write a report.
    Experiment {
        #[command(subcommand)]
        experiment: cli::experiment::Experiment,
    },
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
        Command::Render(args) => cli::render::run(args),
        Command::Export(args) => cli::export::run(args),
        Command::Info(args) => cli::info::run(args),
        Command::Radiosity(args) => cli::radiosity::run(args),
        Command::Plan(args) => cli::plan::run(args),
        Command::Bake(args) => cli::bake::run(args),
        Command::Slurm(args) => cli::slurm::run(args),
        Command::Synth(args) => cli::synth::synth(&args),
        Command::Walk(args) => cli::synth::walk(&args),
        Command::View(args) => cli::view::view(&args),
        Command::Compare(args) => cli::compare::run(args),
        Command::Experiment { experiment } => cli::experiment::run(experiment),
    }
}
