//! Distributed bakes: the job scripts `rangewalk slurm` writes, the shard an
//! array task takes from its environment, `bake --status` and `--finish`;
//! and a real Slurm (munged, slurmctld and slurmd started here on
//! localhost with `tests/slurm/slurm.conf`) running a Cornell box bake as
//! an array of four tasks, once whole and once with a task cancelled and
//! the jobs submitted again, ending each time with the single-machine
//! bake's bits.

use std::net::TcpListener;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use rangewalk::bake::Manifest;
use rangewalk::image::exr_content_hash;

mod common;
use common::{command as rangewalk, scene_arg};

fn run(cmd: &mut Command) -> Output {
    cmd.output().expect("run rangewalk")
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn ok(cmd: &mut Command) -> String {
    let o = run(cmd);
    assert!(o.status.success(), "{cmd:?} failed:\n{}", text(&o));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn fails(cmd: &mut Command, expected: &str) {
    let o = run(cmd);
    assert!(!o.status.success(), "{cmd:?} succeeded:\n{}", text(&o));
    let t = text(&o);
    assert!(t.contains(expected), "{cmd:?}: `{expected}` not in:\n{t}");
}

/// The settings of every bake here: small, yet each image takes long
/// enough (seconds) that a task can be cancelled while rendering.
const SETTINGS: [&str; 8] = [
    "--quality",
    "0.3",
    "--size",
    "64",
    "--spp",
    "800",
    "--backend",
    "bvh",
];

/// Each image's file and checksum in the manifest, and a hash of every bit
/// of its channels and metadata read from the file.
fn images(dir: &Path) -> Vec<(String, Option<String>, u64)> {
    let m = Manifest::read(dir).unwrap();
    assert!(m.complete, "{} is not complete", dir.display());
    m.images
        .iter()
        .map(|e| {
            let sum = exr_content_hash(dir.join(&e.file))
                .unwrap_or_else(|err| panic!("{}: {err:#}", e.file));
            (e.file.clone(), e.fnv1a64.clone(), sum)
        })
        .collect()
}

fn assert_same_bake(a: &Path, b: &Path) {
    assert_eq!(images(a), images(b), "{} and {}", a.display(), b.display());
    let (ma, mb) = (Manifest::read(a).unwrap(), Manifest::read(b).unwrap());
    assert_eq!(ma.plan.views, mb.plan.views);
    assert_eq!(ma.settings, mb.settings);
}

/// Every image file under its final name is whole (it reads), every
/// noise report reads, and every checksum file matches its image: nothing
/// half-written.
fn assert_nothing_half_written(dir: &Path) {
    for entry in std::fs::read_dir(dir.join("images")).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if name.starts_with('.') {
            continue;
        }
        if let Some(image) = name.strip_suffix(".fnv1a64") {
            let recorded = std::fs::read_to_string(&path).unwrap();
            let sum = exr_content_hash(path.with_file_name(image))
                .unwrap_or_else(|e| panic!("{image} has a checksum but does not read: {e:#}"));
            assert_eq!(recorded.trim(), format!("{sum:016x}"), "{name}");
        } else if let Some(image) = name.strip_suffix(".planes") {
            let sum = exr_content_hash(path.with_file_name(image))
                .unwrap_or_else(|e| panic!("{image} has planes but does not read: {e:#}"));
            rangewalk::image::planes_file::verify(&path, &format!("{sum:016x}"))
                .unwrap_or_else(|e| panic!("{name} is half-written: {e:#}"));
        } else if let Some(image) = name.strip_suffix(".noise.json") {
            let report = rangewalk::bake::sampling::read_report(&path.with_file_name(image));
            assert!(report.is_some(), "{name} is half-written");
        } else {
            assert!(name.ends_with(".exr"), "unexpected file {name}");
            exr_content_hash(&path).unwrap_or_else(|e| panic!("{name} is half-written: {e:#}"));
        }
    }
}

#[test]
fn slurm_scripts_carry_every_bake_option() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("b");
    let s = ok(rangewalk().args([
        "slurm",
        &scene_arg("cornell-box"),
        "--quality",
        "0.4",
        "--out",
        out.to_str().unwrap(),
        "--tasks",
        "3",
        "--size",
        "40",
        "--spp",
        "3",
        "--seed",
        "9",
        "--max-depth",
        "4",
        "--indirect",
        "path",
        "--partition",
        "render",
        "--time-limit",
        "1-00:00:00",
        "--cpus-per-task",
        "2",
    ]));
    assert!(
        s.contains("sbatch --parsable --dependency=afterok:$prepare"),
        "{s}"
    );
    let read = |name: &str| std::fs::read_to_string(out.join("slurm").join(name)).unwrap();
    let (prepare, bake, finish) = (
        read("1-prepare.sbatch"),
        read("2-bake.sbatch"),
        read("3-finish.sbatch"),
    );
    for script in [&prepare, &bake, &finish] {
        assert!(script.starts_with("#!/bin/bash\n"), "{script}");
        for line in [
            "#SBATCH --partition=render",
            "#SBATCH --time=1-00:00:00",
            "#SBATCH --cpus-per-task=2",
            "export RAYON_NUM_THREADS=2",
        ] {
            assert!(script.contains(line), "{line} not in {script}");
        }
    }
    assert!(bake.contains("#SBATCH --array=0-2\n"), "{bake}");
    for words in [
        "--quality 0.4",
        "--size 40",
        "--spp 3",
        "--seed 9",
        "--max-depth 4",
        "--indirect path",
    ] {
        assert!(prepare.contains(words) && bake.contains(words), "{words}");
    }
    assert!(prepare.trim_end().ends_with("--prepare"), "{prepare}");
    assert!(bake.trim_end().ends_with("--shard-from-env"), "{bake}");
    assert!(finish.contains(" bake --finish "), "{finish}");
    assert!(out.join("slurm/logs").is_dir());
    // The scripts' folder does not keep the first job from starting there.
    assert!(!out.join("manifest.json").exists());
}

#[test]
fn slurm_and_shard_errors_name_what_is_wrong() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("b");
    let o = out.to_str().unwrap();
    let scene = scene_arg("cornell-box");
    let slurm = |extra: &[&str]| {
        let mut c = rangewalk();
        c.args(["slurm", &scene, "--quality", "0.3", "--out", o]);
        c.args(extra);
        c
    };
    fails(&mut slurm(&["--tasks", "0"]), "--tasks");
    fails(
        &mut slurm(&["--tasks", "2", "--time-limit", "2h"]),
        "--time-limit `2h`",
    );
    fails(
        &mut slurm(&["--tasks", "2", "--partition", "a;b"]),
        "--partition `a;b`",
    );
    std::fs::create_dir_all(tmp.path().join("other")).unwrap();
    std::fs::write(tmp.path().join("other/notes.txt"), "mine").unwrap();
    let mut c = rangewalk();
    c.args(["slurm", &scene, "--quality", "0.3", "--tasks", "2", "--out"])
        .arg(tmp.path().join("other"));
    fails(&mut c, "is not a bake");
    let mut c = rangewalk();
    c.args(["bake", &scene, "--out", o, "--shard-from-env"])
        .args(SETTINGS)
        .env_remove("SLURM_ARRAY_TASK_ID");
    fails(&mut c, "SLURM_ARRAY_TASK_ID is not set");
    let mut c = rangewalk();
    c.args(["bake", &scene, "--out", o, "--shard-from-env"])
        .args(SETTINGS)
        .env("SLURM_ARRAY_TASK_ID", "3")
        .env("SLURM_ARRAY_TASK_COUNT", "1");
    fails(
        &mut c,
        "SLURM_ARRAY_TASK_ID 3 is not below SLURM_ARRAY_TASK_COUNT 1",
    );
    fails(
        rangewalk().args(["bake", "--status", o]),
        "holds no bake yet",
    );
    fails(
        rangewalk().args(["bake", "--status", o, "--spp", "2"]),
        "cannot be used with",
    );
}

#[test]
fn status_and_finish_follow_a_sharded_bake() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("b");
    let o = out.to_str().unwrap();
    let scene = scene_arg("cornell-box");
    let bake = || {
        let mut c = rangewalk();
        c.args([
            "bake",
            &scene,
            "--out",
            o,
            "--quality",
            "0.3",
            "--size",
            "24",
        ])
        .args(["--spp", "1", "--backend", "bvh"]);
        c
    };
    let status = || ok(rangewalk().args(["bake", "--status", o]));
    ok(bake().arg("--prepare"));
    let s = status();
    assert!(
        s.contains("0 of 4 images done (0%); radiosity solved; not complete"),
        "{s}"
    );
    ok(bake()
        .arg("--shard-from-env")
        .env("SLURM_ARRAY_TASK_ID", "0")
        .env("SLURM_ARRAY_TASK_COUNT", "2"));
    let s = status();
    assert!(s.contains("2 of 4 images done (50%)"), "{s}");
    assert!(
        s.contains("images/v000-t001.exr, images/v001-t001.exr"),
        "{s}"
    );
    fails(
        rangewalk().args(["bake", "--finish", o]),
        "2 of 4 images missing or damaged: images/v000-t001.exr, images/v001-t001.exr",
    );
    assert!(!Manifest::read(&out).unwrap().complete);
    ok(bake().args(["--shard", "1/2"]));
    let s = ok(rangewalk().args(["bake", "--finish", o]));
    assert!(s.contains("bake complete"), "{s}");
    assert!(status().contains("4 of 4 images done (100%); radiosity solved; bake complete"));
    // A finished image changed afterwards fails the check, by name.
    let victim = out.join("images/v001-t000.exr");
    let mut bytes = std::fs::read(&victim).unwrap();
    let n = bytes.len();
    bytes.truncate(n / 2);
    std::fs::write(&victim, bytes).unwrap();
    fails(
        rangewalk().args(["bake", "--finish", o]),
        "1 of 4 images missing or damaged: images/v001-t000.exr",
    );
}

/// A one-node Slurm cluster on localhost, stopped (daemons by their
/// process ids) and its state directory removed when dropped.
struct Cluster {
    conf: PathBuf,
    daemons: Vec<(&'static str, Child)>,
    logs: Vec<PathBuf>,
    state: tempfile::TempDir,
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port on localhost")
}

fn program(name: &str) -> PathBuf {
    for dir in ["/usr/sbin", "/usr/bin", "/sbin", "/bin"] {
        let p = Path::new(dir).join(name);
        if p.exists() {
            return p;
        }
    }
    panic!("{name} is not installed: `make deps` installs Debian's slurm-wlm and munge");
}

impl Cluster {
    fn start() -> Cluster {
        let state = tempfile::tempdir().unwrap();
        let root = state.path().to_path_buf();
        // munged checks that every folder on the way to its socket lets
        // everyone through.
        std::fs::set_permissions(&root, std::fs::Permissions::from_mode(0o755)).unwrap();
        for d in ["munge", "ctld", "slurmd"] {
            std::fs::create_dir(root.join(d)).unwrap();
        }
        std::fs::set_permissions(root.join("munge"), std::fs::Permissions::from_mode(0o711))
            .unwrap();
        let host = Command::new("hostname").arg("-s").output().unwrap();
        let host = String::from_utf8_lossy(&host.stdout).trim().to_string();
        assert!(!host.is_empty(), "`hostname -s` names no host");
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        let template = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/slurm/slurm.conf");
        let conf_text = std::fs::read_to_string(&template)
            .unwrap()
            .replace("@STATE@", &root.to_string_lossy())
            .replace("@HOST@", &host)
            .replace("@CPUS@", &cpus.to_string())
            .replace("@CTLD_PORT@", &free_port().to_string())
            .replace("@SLURMD_PORT@", &free_port().to_string());
        assert!(
            !conf_text
                .lines()
                .any(|l| !l.starts_with('#') && l.contains('@')),
            "a placeholder left in {conf_text}"
        );
        let conf = root.join("slurm.conf");
        std::fs::write(&conf, conf_text).unwrap();

        let key = root.join("munge/munge.key");
        let o = Command::new(program("mungekey"))
            .arg("--create")
            .arg(format!("--keyfile={}", key.display()))
            .output()
            .unwrap();
        assert!(o.status.success(), "mungekey: {}", text(&o));

        let mut cluster = Cluster {
            conf,
            daemons: Vec::new(),
            logs: Vec::new(),
            state,
        };
        let m = |f: &str| format!("{}", root.join("munge").join(f).display());
        cluster.spawn(
            "munged",
            &[
                "--foreground".into(),
                format!("--key-file={}", key.display()),
                format!("--socket={}", m("munge.socket")),
                format!("--pid-file={}", m("munged.pid")),
                format!("--log-file={}", m("munged.log")),
                format!("--seed-file={}", m("munged.seed")),
            ],
            root.join("munge/munged.log"),
        );
        let socket = root.join("munge/munge.socket");
        cluster.wait_for("munged to open its socket", |_| socket.exists());
        let conf = cluster.conf.to_string_lossy().into_owned();
        cluster.spawn(
            "slurmctld",
            &["-D".into(), "-f".into(), conf.clone()],
            root.join("slurmctld.log"),
        );
        cluster.spawn(
            "slurmd",
            &["-D".into(), "-f".into(), conf, "-N".into(), host],
            root.join("slurmd.log"),
        );
        cluster.wait_for("the node to be idle", |c| {
            c.output("sinfo", &["-h", "-o", "%T"]).trim() == "idle"
        });
        cluster
    }

    /// Starts a daemon in the foreground, its output in `state/<name>.out`.
    fn spawn(&mut self, name: &'static str, args: &[String], log: PathBuf) {
        let out = std::fs::File::create(self.state.path().join(format!("{name}.out"))).unwrap();
        let child = Command::new(program(name))
            .args(args)
            .env("SLURM_CONF", &self.conf)
            .stdout(out.try_clone().unwrap())
            .stderr(out)
            .stdin(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("starting {name}: {e}"));
        self.daemons.push((name, child));
        self.logs
            .push(self.state.path().join(format!("{name}.out")));
        self.logs.push(log);
    }

    /// The daemons' logs, for a failure's message.
    fn logs(&self) -> String {
        self.logs
            .iter()
            .map(|p| {
                let t = std::fs::read_to_string(p).unwrap_or_default();
                let tail: Vec<&str> = t.lines().rev().take(15).collect();
                let tail: Vec<&str> = tail.into_iter().rev().collect();
                format!("--- {}\n{}", p.display(), tail.join("\n"))
            })
            .collect::<Vec<_>>()
            .join("\n")
    }

    /// Waits (at most three minutes) until `done` holds; fails with the
    /// daemons' logs if it does not, or if a daemon stops.
    fn wait_for(&mut self, what: &str, done: impl Fn(&Cluster) -> bool) {
        let start = Instant::now();
        loop {
            if done(self) {
                return;
            }
            for (name, child) in &mut self.daemons {
                if let Some(status) = child.try_wait().unwrap() {
                    let name = *name;
                    panic!(
                        "{name} stopped ({status}) while waiting for {what}; the daemons could not run here:\n{}",
                        self.logs()
                    );
                }
            }
            if start.elapsed() > Duration::from_secs(180) {
                panic!("timed out waiting for {what}:\n{}", self.logs());
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    fn command(&self, program: &str) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf);
        c
    }

    fn output(&self, program: &str, args: &[&str]) -> String {
        let o = self.command(program).args(args).output().unwrap();
        String::from_utf8_lossy(&o.stdout).into_owned()
    }

    /// `JobState` of a job or array task the controller still knows.
    fn state_of(&self, job: &str) -> String {
        let s = self.output("scontrol", &["-o", "show", "job", job]);
        s.split_whitespace()
            .find_map(|w| w.strip_prefix("JobState="))
            .unwrap_or("UNKNOWN")
            .to_string()
    }

    /// Whether any of `jobs` is still pending or running.
    fn queued(&self, jobs: &Jobs) -> bool {
        let ids = format!("{},{},{}", jobs.prepare, jobs.bake, jobs.finish);
        !self
            .output("squeue", &["-h", "-j", &ids, "-o", "%i"])
            .trim()
            .is_empty()
    }

    /// Submits a four-task bake into `dir`, waits for its jobs to end and
    /// requires every job and task to have completed; returns the jobs and
    /// the seconds from submission to the end.
    fn bake_to_the_end(&mut self, dir: &Path) -> (Jobs, f64) {
        let start = Instant::now();
        let jobs = self.submit(dir);
        self.wait_for("the jobs to end", |c| !c.queued(&jobs));
        let seconds = start.elapsed().as_secs_f64();
        let tasks = (0..4).map(|t| format!("{}_{t}", jobs.bake));
        for id in [jobs.prepare.clone(), jobs.finish.clone()]
            .into_iter()
            .chain(tasks)
        {
            assert_eq!(self.state_of(&id), "COMPLETED", "job {id}\n{}", self.logs());
        }
        (jobs, seconds)
    }

    /// `rangewalk slurm ... --submit` for a four-task bake into `dir`.
    fn submit(&self, dir: &Path) -> Jobs {
        let mut c = rangewalk();
        c.env("SLURM_CONF", &self.conf)
            .args(["slurm", &scene_arg("cornell-box"), "--out"])
            .arg(dir)
            .args(SETTINGS)
            .args(["--tasks", "4", "--submit"]);
        let out = ok(&mut c);
        let id = |script: &str| {
            out.lines()
                .find_map(|l| l.strip_prefix(&format!("submitted {script} as job ")))
                .and_then(|rest| rest.split_whitespace().next())
                .unwrap_or_else(|| panic!("no job id for {script} in:\n{out}"))
                .to_string()
        };
        Jobs {
            prepare: id("1-prepare.sbatch"),
            bake: id("2-bake.sbatch"),
            finish: id("3-finish.sbatch"),
        }
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        // Every job on this private cluster is the test's.
        let jobs = self.output("squeue", &["-h", "-o", "%i"]);
        let jobs: Vec<&str> = jobs.split_whitespace().collect();
        if !jobs.is_empty() {
            let _ = self.command("scancel").args(&jobs).status();
            let start = Instant::now();
            while !self.output("squeue", &["-h", "-o", "%i"]).trim().is_empty()
                && start.elapsed() < Duration::from_secs(20)
            {
                std::thread::sleep(Duration::from_millis(200));
            }
        }
        // Stopped by process id, the last started first.
        for (_, child) in self.daemons.iter_mut().rev() {
            let _ = Command::new("kill")
                .args(["-TERM", &child.id().to_string()])
                .status();
            let start = Instant::now();
            while child.try_wait().ok().flatten().is_none() {
                if start.elapsed() > Duration::from_secs(10) {
                    let _ = child.kill();
                    let _ = child.wait();
                    break;
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        }
    }
}

struct Jobs {
    prepare: String,
    bake: String,
    finish: String,
}

/// The images the tasks of array `job` rendered and found done, from their
/// logs.
fn rendered_and_reused(dir: &Path, job: &str) -> (usize, usize) {
    let mut totals = (0, 0);
    for task in 0..4 {
        let log = dir.join(format!("slurm/logs/bake-{job}_{task}.out"));
        let t = std::fs::read_to_string(&log).unwrap_or_else(|e| panic!("{}: {e}", log.display()));
        let line = t
            .lines()
            .find(|l| l.starts_with("images (shard "))
            .unwrap_or_else(|| panic!("no summary in {}:\n{t}", log.display()));
        let n: Vec<usize> = line
            .split(|c: char| !c.is_ascii_digit())
            .filter_map(|w| w.parse().ok())
            .collect();
        // `images (shard i/n): R rendered, D already done; F of T ...`
        totals.0 += n[2];
        totals.1 += n[3];
    }
    totals
}

#[test]
fn a_slurm_array_bake_equals_the_single_machine_bake_even_with_a_task_cancelled() {
    let tmp = tempfile::tempdir().unwrap();
    let single = tmp.path().join("single");
    let start = Instant::now();
    ok(rangewalk()
        .args(["bake", &scene_arg("cornell-box"), "--out"])
        .arg(&single)
        .args(SETTINGS));
    println!(
        "single-machine bake: {:.1} s",
        start.elapsed().as_secs_f64()
    );

    let start = Instant::now();
    let mut cluster = Cluster::start();
    println!("daemons up: {:.1} s", start.elapsed().as_secs_f64());

    // The whole bake as four array tasks between its two single jobs.
    let whole = tmp.path().join("whole");
    let (jobs, seconds) = cluster.bake_to_the_end(&whole);
    println!(
        "jobs {} (prepare), {} (array of 4), {} (finish): {seconds:.1} s from submission to complete",
        jobs.prepare, jobs.bake, jobs.finish
    );
    assert_same_bake(&single, &whole);
    assert_eq!(rendered_and_reused(&whole, &jobs.bake), (4, 0));
    let s = ok(rangewalk().arg("bake").arg("--status").arg(&whole));
    assert!(
        s.contains("4 of 4 images done (100%)") && s.contains("bake complete"),
        "{s}"
    );

    // Task 1 cancelled while it renders: the finishing job is then never
    // run, and the bake is left unfinished with nothing half-written.
    let cut = tmp.path().join("cancelled");
    let jobs = cluster.submit(&cut);
    let task = format!("{}_1", jobs.bake);
    cluster.wait_for("task 1 to run", |c| c.state_of(&task) == "RUNNING");
    let o = cluster.command("scancel").arg(&task).output().unwrap();
    assert!(o.status.success(), "scancel {task}: {}", text(&o));
    // Task 1's one image is the manifest's second.
    let its_image = cut.join("images/v000-t001.exr.fnv1a64");
    assert!(
        !its_image.exists(),
        "task 1 finished its image before it was cancelled: the test's images are too fast"
    );
    cluster.wait_for("the jobs to end", |c| !c.queued(&jobs));
    assert_eq!(cluster.state_of(&task), "CANCELLED");
    assert_ne!(cluster.state_of(&jobs.finish), "COMPLETED");
    assert!(!its_image.exists());
    assert!(!Manifest::read(&cut).unwrap().complete);
    assert_nothing_half_written(&cut);
    let s = ok(rangewalk().arg("bake").arg("--status").arg(&cut));
    assert!(s.contains("3 of 4 images done (75%)"), "{s}");

    // Submitted again, the tasks render only the missing image.
    let (again, seconds) = cluster.bake_to_the_end(&cut);
    println!(
        "resubmitted as jobs {}, {}, {}: {seconds:.1} s to complete",
        again.prepare, again.bake, again.finish
    );
    assert_eq!(rendered_and_reused(&cut, &again.bake), (1, 3));
    assert_same_bake(&single, &cut);
    drop(cluster);
}
