//! Bakes beyond one machine, on the scheduler a cluster already has:
//! Slurm job scripts that need nothing but the `rangewalk` binary and a
//! bake directory every node sees.
//!
//! Three jobs: one for the object-space stages (plan, simplification and
//! radiosity, solved once), an array of `n` tasks that each render one
//! shard of the images (`afterok` on the first), and one that reads every
//! image back against its checksum and marks the bake complete (`afterok`
//! on the whole array). Every file a task writes is renamed into place
//! once whole and every image is seeded by its (view, time), so a task
//! that is killed, preempted or requeued leaves nothing half-written and
//! running it (or the whole set) again finishes the bake with the same
//! bits as a single-machine bake.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, ensure, Context, Result};

use super::{Shard, SLURM_DIR};

pub const PREPARE: &str = "1-prepare.sbatch";
pub const BAKE: &str = "2-bake.sbatch";
pub const FINISH: &str = "3-finish.sbatch";
/// Where the jobs' output goes, inside the bake's `slurm/` folder.
pub const LOGS: &str = "logs";

/// The shard of the Slurm array task this process runs in.
pub fn shard_from_env() -> Result<Shard> {
    shard_from(|name| std::env::var(name).ok())
}

/// The shard named by `SLURM_ARRAY_TASK_ID` and `SLURM_ARRAY_TASK_COUNT`
/// as `var` looks them up.
pub fn shard_from(var: impl Fn(&str) -> Option<String>) -> Result<Shard> {
    let read = |name: &str| -> Result<u32> {
        let value = var(name).with_context(|| {
            format!("--shard-from-env: {name} is not set (not inside a Slurm array task?); pass --shard i/n instead")
        })?;
        value
            .trim()
            .parse()
            .with_context(|| format!("--shard-from-env: {name} is `{value}`, not a count"))
    };
    let (index, count) = (
        read("SLURM_ARRAY_TASK_ID")?,
        read("SLURM_ARRAY_TASK_COUNT")?,
    );
    ensure!(
        count > 0 && index < count,
        "--shard-from-env: SLURM_ARRAY_TASK_ID {index} is not below SLURM_ARRAY_TASK_COUNT {count}: \
         the array must run indices 0 to n-1; to run a task again, submit the job scripts again \
         (`rangewalk slurm ... --submit`: every task keeps its finished images and renders the rest)"
    );
    Ok(Shard { index, count })
}

/// What the jobs ask of the scheduler beyond the defaults.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct JobOptions {
    pub partition: Option<String>,
    /// Slurm's `--time`: minutes, `MM:SS`, `HH:MM:SS` or `D-HH:MM:SS`.
    pub time_limit: Option<String>,
    /// CPUs of every job; the renderer then uses that many threads.
    pub cpus_per_task: Option<u32>,
}

/// The job scripts written into a bake directory.
#[derive(Clone, Debug, PartialEq)]
pub struct Scripts {
    pub prepare: PathBuf,
    pub bake: PathBuf,
    pub finish: PathBuf,
    /// Tasks of the bake array.
    pub tasks: u32,
}

/// Writes `<dir>/slurm/1-prepare.sbatch`, `2-bake.sbatch` (an array of
/// `tasks` tasks, indices from 0) and `3-finish.sbatch`, and the folder
/// for their logs. `program` is the `rangewalk` binary and `bake_args` the
/// arguments of `rangewalk bake` that name the scene, the bake directory
/// (`dir`) and every setting, all as the nodes will see them.
pub fn write_scripts(
    dir: &Path,
    program: &Path,
    bake_args: &[String],
    tasks: u32,
    job: &JobOptions,
) -> Result<Scripts> {
    ensure!(tasks > 0, "--tasks must be at least 1");
    ensure!(
        dir.is_absolute() && program.is_absolute(),
        "the bake directory and the program must be absolute paths for the nodes"
    );
    let slurm = dir.join(SLURM_DIR);
    let logs = slurm.join(LOGS);
    check_directive_path(&logs)?;
    check_options(job)?;
    std::fs::create_dir_all(&logs).with_context(|| format!("creating {}", logs.display()))?;
    let program = program.to_string_lossy();
    let bake = |extra: &str| {
        let mut line = format!("exec {} bake", quote(&program));
        for a in bake_args {
            let _ = write!(line, " {}", quote(a));
        }
        line + " " + extra
    };
    let dir_arg = quote(&dir.to_string_lossy());
    let logs = logs.to_string_lossy();
    let scripts = Scripts {
        prepare: slurm.join(PREPARE),
        bake: slurm.join(BAKE),
        finish: slurm.join(FINISH),
        tasks,
    };
    let texts = [
        (
            &scripts.prepare,
            script(
                "step 1 of 3: plan the views and times and solve radiosity, once",
                &[
                    "--job-name=rangewalk-prepare".into(),
                    format!("--output={logs}/prepare-%j.out"),
                ],
                job,
                &bake("--prepare"),
            ),
        ),
        (
            &scripts.bake,
            script(
                &format!(
                    "step 2 of 3: render the base images as {tasks} array tasks, each its shard \
                     SLURM_ARRAY_TASK_ID/SLURM_ARRAY_TASK_COUNT;\n# a task killed or requeued \
                     keeps its finished images and renders the rest when it runs again"
                ),
                &[
                    "--job-name=rangewalk-bake".into(),
                    format!("--array=0-{}", tasks - 1),
                    format!("--output={logs}/bake-%A_%a.out"),
                    "--open-mode=append".into(),
                    "--requeue".into(),
                    "--kill-on-invalid-dep=yes".into(),
                ],
                job,
                &bake("--shard-from-env"),
            ),
        ),
        (
            &scripts.finish,
            script(
                "step 3 of 3: read every image back against its checksum and mark the bake complete",
                &[
                    "--job-name=rangewalk-finish".into(),
                    format!("--output={logs}/finish-%j.out"),
                    "--kill-on-invalid-dep=yes".into(),
                ],
                job,
                &format!("exec {} bake --finish {dir_arg}", quote(&program)),
            ),
        ),
    ];
    for (path, text) in texts {
        crate::output::write_file(path, text)?;
    }
    Ok(scripts)
}

fn script(what: &str, directives: &[String], job: &JobOptions, command: &str) -> String {
    let mut s = String::from("#!/bin/bash\n");
    let _ = writeln!(s, "# rangewalk bake, {what}.");
    s.push_str("# Written by `rangewalk slurm`; submit the three scripts in order, each after the one before (afterok).\n");
    for d in directives {
        let _ = writeln!(s, "#SBATCH {d}");
    }
    if let Some(p) = &job.partition {
        let _ = writeln!(s, "#SBATCH --partition={p}");
    }
    if let Some(t) = &job.time_limit {
        let _ = writeln!(s, "#SBATCH --time={t}");
    }
    if let Some(n) = job.cpus_per_task {
        let _ = writeln!(s, "#SBATCH --cpus-per-task={n}");
    }
    s.push_str("set -euo pipefail\n");
    if let Some(n) = job.cpus_per_task {
        let _ = writeln!(s, "export RAYON_NUM_THREADS={n}");
    }
    s.push_str(command);
    s.push('\n');
    s
}

/// `#SBATCH` lines are not shell: a path in them must need no quoting,
/// and `%` would be taken for one of Slurm's file name patterns.
fn check_directive_path(path: &Path) -> Result<()> {
    let p = path.to_string_lossy();
    if let Some(c) = p
        .chars()
        .find(|c| c.is_whitespace() || "%'\"\\".contains(*c))
    {
        bail!(
            "{p}: Slurm's #SBATCH --output cannot take a path with {c:?} in it; choose a bake directory without it"
        );
    }
    Ok(())
}

fn check_options(job: &JobOptions) -> Result<()> {
    if let Some(p) = &job.partition {
        ensure!(
            !p.is_empty()
                && p.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "_-.,".contains(c)),
            "--partition `{p}` is not a Slurm partition name (letters, digits, `_-.,`)"
        );
    }
    if let Some(t) = &job.time_limit {
        ensure!(
            !t.is_empty()
                && t.chars()
                    .all(|c| c.is_ascii_digit() || c == ':' || c == '-')
                && t.chars().next().is_some_and(|c| c.is_ascii_digit()),
            "--time-limit `{t}` is not a Slurm time (minutes, MM:SS, HH:MM:SS or D-HH:MM:SS)"
        );
    }
    if job.cpus_per_task == Some(0) {
        bail!("--cpus-per-task must be at least 1");
    }
    Ok(())
}

/// A word for bash: as it is where that is safe, else single-quoted.
fn quote(s: &str) -> String {
    let safe = !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@".contains(c));
    if safe {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

/// The job ids `sbatch` gave the three jobs.
#[derive(Clone, Debug, PartialEq)]
pub struct Submitted {
    pub prepare: String,
    pub bake: String,
    pub finish: String,
}

/// Submits the three jobs with `sbatch`, each depending on the one before
/// (`afterok`).
pub fn submit(scripts: &Scripts) -> Result<Submitted> {
    let prepare = sbatch(&scripts.prepare, None)?;
    let bake = sbatch(&scripts.bake, Some(&prepare))?;
    let finish = sbatch(&scripts.finish, Some(&bake))?;
    Ok(Submitted {
        prepare,
        bake,
        finish,
    })
}

fn sbatch(script: &Path, after: Option<&str>) -> Result<String> {
    let mut cmd = Command::new("sbatch");
    cmd.arg("--parsable");
    if let Some(job) = after {
        cmd.arg(format!("--dependency=afterok:{job}"));
    }
    let out = cmd.arg(script).output().map_err(|e| {
        anyhow::anyhow!(
            "running sbatch for {}: {e} (is Slurm's client, Debian's slurm-client, installed and on PATH?)",
            script.display()
        )
    })?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        bail!(
            "sbatch {} failed ({}): {}",
            script.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    // `--parsable` prints `<id>` or `<id>;<cluster>`.
    let id = stdout.trim().split(';').next().unwrap_or("");
    ensure!(
        !id.is_empty() && id.chars().all(|c| c.is_ascii_digit()),
        "sbatch {} printed `{}`, not a job id",
        script.display(),
        stdout.trim()
    );
    Ok(id.to_string())
}

/// The shell commands that submit the scripts as [`submit`] does.
pub fn submit_commands(scripts: &Scripts) -> String {
    let q = |p: &Path| quote(&p.to_string_lossy());
    format!(
        "prepare=$(sbatch --parsable {})\n\
         bake=$(sbatch --parsable --dependency=afterok:$prepare {})\n\
         sbatch --dependency=afterok:$bake {}",
        q(&scripts.prepare),
        q(&scripts.bake),
        q(&scripts.finish)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |name| {
            vars.iter()
                .find(|(k, _)| *k == name)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn the_shard_comes_from_the_array_task() {
        let s = shard_from(env(&[
            ("SLURM_ARRAY_TASK_ID", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
        ]))
        .unwrap();
        assert_eq!(s, Shard { index: 2, count: 4 });
        let missing = shard_from(env(&[("SLURM_ARRAY_TASK_ID", "2")])).unwrap_err();
        assert!(
            format!("{missing:#}").contains("SLURM_ARRAY_TASK_COUNT is not set"),
            "{missing:#}"
        );
        let garbled = shard_from(env(&[
            ("SLURM_ARRAY_TASK_ID", "x"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
        ]))
        .unwrap_err();
        assert!(format!("{garbled:#}").contains("`x`"), "{garbled:#}");
        // One index of the array submitted alone: its count is 1.
        let alone = shard_from(env(&[
            ("SLURM_ARRAY_TASK_ID", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "1"),
        ]))
        .unwrap_err();
        assert!(
            format!("{alone:#}").contains("submit the job scripts again"),
            "{alone:#}"
        );
    }

    #[test]
    fn words_are_quoted_only_where_bash_needs_it() {
        assert_eq!(quote("/a/b-c_d.toml"), "/a/b-c_d.toml");
        assert_eq!(quote("a b"), "'a b'");
        assert_eq!(quote("it's"), r"'it'\''s'");
        assert_eq!(quote("$HOME"), "'$HOME'");
        assert_eq!(quote(""), "''");
    }

    #[test]
    fn job_options_are_checked() {
        let bad = [
            JobOptions {
                partition: Some("a b".into()),
                ..JobOptions::default()
            },
            JobOptions {
                time_limit: Some("1h".into()),
                ..JobOptions::default()
            },
            JobOptions {
                cpus_per_task: Some(0),
                ..JobOptions::default()
            },
        ];
        for (job, name) in bad
            .iter()
            .zip(["--partition", "--time-limit", "--cpus-per-task"])
        {
            let e = check_options(job).unwrap_err();
            assert!(e.to_string().contains(name), "{e}");
        }
        check_options(&JobOptions {
            partition: Some("gpu_a100".into()),
            time_limit: Some("1-02:00:00".into()),
            cpus_per_task: Some(8),
        })
        .unwrap();
    }
}
