//! `rangewalk slurm`: a distributed bake as Slurm jobs.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use rangewalk::bake::{self, slurm};
use rangewalk::image;
use rangewalk::quality::Quality;

use super::bake_options::BakeOptions;
use super::load;

/// `rangewalk slurm`.
#[derive(clap::Args)]
pub struct SlurmArgs {
    scene: PathBuf,
    /// Quality in [0, 1] of every stage: views, times, radiosity.
    #[arg(long)]
    quality: Quality,
    /// Bake directory, on a filesystem every node sees; the job scripts go
    /// into its `slurm/` folder.
    #[arg(long)]
    out: PathBuf,
    /// Tasks of the bake array (each renders every n-th image).
    #[arg(long)]
    tasks: u32,
    #[command(flatten)]
    options: BakeOptions,
    /// Slurm partition of every job.
    #[arg(long)]
    partition: Option<String>,
    /// Slurm time limit of every job (minutes, MM:SS, HH:MM:SS or D-HH:MM:SS).
    #[arg(long)]
    time_limit: Option<String>,
    /// CPUs of every job; the renderer uses that many threads.
    #[arg(long)]
    cpus_per_task: Option<u32>,
    /// Submit the jobs with sbatch and print their ids.
    #[arg(long)]
    submit: bool,
}

/// `rangewalk slurm`: the job scripts of a distributed bake, submitted or
/// with the commands that submit them.
pub fn run(a: SlurmArgs) -> Result<()> {
    let quality = a.quality;
    image::check_output_dir("--out", &a.out)?;
    let s = load(&a.scene)?;
    let (settings, sampling, why) = a.options.settings(&s, quality)?;
    if a.tasks == 0 {
        bail!("--tasks must be at least 1");
    }
    bake::check_resumable(&s, &a.out, &settings, &sampling)?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let absolute =
        |p: &Path| std::fs::canonicalize(p).with_context(|| format!("resolving {}", p.display()));
    let (dir, scene) = (absolute(&a.out)?, absolute(&a.scene)?);
    let program = absolute(&std::env::current_exe().context("finding the rangewalk binary")?)?;
    let mut words = vec![
        scene.to_string_lossy().into_owned(),
        "--quality".into(),
        quality.get().to_string(),
        "--out".into(),
        dir.to_string_lossy().into_owned(),
    ];
    words.extend(a.options.words());
    let job = slurm::JobOptions {
        partition: a.partition,
        time_limit: a.time_limit,
        cpus_per_task: a.cpus_per_task,
    };
    let scripts = slurm::write_scripts(&dir, &program, &words, a.tasks, &job)?;
    println!("{why}");
    println!(
        "job scripts for {} tasks in {}:",
        a.tasks,
        dir.join(bake::SLURM_DIR).display()
    );
    for p in [&scripts.prepare, &scripts.bake, &scripts.finish] {
        println!("  {}", p.display());
    }
    if a.submit {
        let ids = slurm::submit(&scripts)?;
        println!("submitted {} as job {}", slurm::PREPARE, ids.prepare);
        println!(
            "submitted {} as job {} (tasks 0-{}, after job {})",
            slurm::BAKE,
            ids.bake,
            a.tasks - 1,
            ids.prepare
        );
        println!(
            "submitted {} as job {} (after job {})",
            slurm::FINISH,
            ids.finish,
            ids.bake
        );
        println!(
            "watch: squeue -j {},{},{}; rangewalk bake --status {}",
            ids.prepare,
            ids.bake,
            ids.finish,
            dir.display()
        );
    } else {
        println!("submit them with:\n{}", slurm::submit_commands(&scripts));
    }
    Ok(())
}
