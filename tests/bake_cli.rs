//! `rangewalk bake` as a user runs it: killed at any moment and started
//! again it ends with the images of an uninterrupted bake; its errors name
//! what is wrong.

use std::path::Path;
use std::process::{Child, Command, Output};
use std::time::{Duration, Instant};

use rangewalk::bake::Manifest;
use rangewalk::image::exr_content_hash;

mod common;
use common::{rangewalk as run, scene_arg as scene};

fn args<'a>(scene: &'a str, out: &'a str) -> Vec<&'a str> {
    vec![
        "bake",
        scene,
        "--quality",
        "0.3",
        "--out",
        out,
        "--size",
        "96",
        "--spp",
        "8",
        "--backend",
        "bvh",
    ]
}

fn spawn(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_rangewalk"))
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("start rangewalk")
}

/// Kills `child` as soon as `ready` holds; returns whether it was still
/// running then (else it finished before it could be interrupted).
fn kill_when(mut child: Child, ready: impl Fn() -> bool) -> bool {
    let start = Instant::now();
    while !ready() {
        if child.try_wait().unwrap().is_some() || start.elapsed() > Duration::from_secs(300) {
            return false;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    let running = child.try_wait().unwrap().is_none();
    child.kill().unwrap();
    child.wait().unwrap();
    running
}

fn checksums(dir: &Path) -> usize {
    std::fs::read_dir(dir.join("images"))
        .map(|d| {
            d.filter(|e| {
                e.as_ref()
                    .is_ok_and(|e| e.file_name().to_string_lossy().ends_with(".fnv1a64"))
            })
            .count()
        })
        .unwrap_or(0)
}

/// Each image's file and a hash of every bit of its channels and metadata.
fn images(dir: &Path) -> Vec<(String, u64)> {
    let m = Manifest::read(dir).unwrap();
    assert!(m.complete, "{} is not complete", dir.display());
    m.images
        .iter()
        .map(|e| (e.file.clone(), exr_content_hash(dir.join(&e.file)).unwrap()))
        .collect()
}

#[test]
fn a_killed_bake_started_again_equals_an_uninterrupted_one() {
    let scene = scene("cornell-box");
    let tmp = tempfile::tempdir().unwrap();
    let whole = tmp.path().join("whole");
    let killed = tmp.path().join("killed");
    let (w, k) = (whole.to_str().unwrap(), killed.to_str().unwrap());

    let o = run(&args(&scene, w));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    // Killed while solving radiosity (the manifest is written first) ...
    let manifest = killed.join("manifest.json");
    assert!(kill_when(spawn(&args(&scene, k)), || manifest.exists()));
    assert!(!Manifest::read(&killed).unwrap().complete);
    // ... then while rendering, right after the first image is finished ...
    let before = checksums(&killed);
    assert!(kill_when(spawn(&args(&scene, k)), || checksums(&killed) > before));
    let m = Manifest::read(&killed).unwrap();
    assert!(!m.complete && checksums(&killed) < m.images.len());
    // ... and finished by the same command.
    let o = run(&args(&scene, k));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("already done") && out.contains("bake complete"),
        "{out}"
    );

    assert_eq!(images(&whole), images(&killed));
    let (a, b) = (
        Manifest::read(&whole).unwrap(),
        Manifest::read(&killed).unwrap(),
    );
    assert_eq!(a.images, b.images);
    assert_eq!(a.plan.views, b.plan.views);
    // No temporary file is left looking like an image.
    for e in std::fs::read_dir(killed.join("images")).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().into_owned();
        assert!(
            name.starts_with('.')
                || name.ends_with(".exr")
                || name.ends_with(".exr.planes")
                || name.ends_with(".noise.json")
                || name.ends_with(".fnv1a64"),
            "{name}"
        );
    }
}

#[test]
fn bake_errors_name_the_option_or_file_at_fault() {
    let scene = scene("cornell-box");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("b");
    let o = out.to_str().unwrap();
    let cases: [(Vec<&str>, &str); 4] = [
        (
            vec!["bake", &scene, "--quality", "1.5", "--out", o],
            "--quality",
        ),
        (
            vec![
                "bake",
                &scene,
                "--quality",
                "0.3",
                "--out",
                o,
                "--shard",
                "2/2",
            ],
            "shard `2/2`",
        ),
        (
            vec!["bake", &scene, "--quality", "0.3", "--out", o, "--spp", "0"],
            "--spp",
        ),
        (
            vec![
                "bake",
                "/nonexistent/scene.toml",
                "--quality",
                "0.3",
                "--out",
                o,
            ],
            "/nonexistent/scene.toml",
        ),
    ];
    for (a, expect) in cases {
        let r = run(&a);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success() && err.contains(expect), "{a:?}: {err}");
    }
    // Sampling: each bad value named with its option; nothing is made.
    for (extra, expect) in [
        (vec!["--noise", "0"], "--noise 0 is not a relative error"),
        (
            vec!["--noise", "-0.1"],
            "--noise -0.1 is not a relative error",
        ),
        (
            vec!["--noise", "NaN"],
            "--noise NaN is not a relative error",
        ),
        (
            vec!["--noise", "1.5"],
            "--noise 1.5 is not a relative error",
        ),
        (vec!["--noise", "lots"], "`lots` is not a number"),
        (vec!["--max-spp", "4"], "--max-spp 4 is below --spp 8"),
        (
            vec!["--noise", "off", "--max-spp", "64"],
            "--max-spp 64 applies with a --noise target only",
        ),
    ] {
        let a = with(args(&scene, o), &extra);
        let r = run(&a);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success() && err.contains(expect), "{a:?}: {err}");
        assert!(!out.exists(), "{a:?} made {}", out.display());
    }
    // A folder that holds something else is not written into.
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let r = run(&args(&scene, o));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("not a bake"), "{err}");
}

/// A bake to a noise target reports the noise each image reached, beside
/// it and then in the manifest, and `--status` sums it up; resuming it with
/// another target is refused naming both, while naming the default limit
/// is the same bake.
#[test]
fn noise_reports_are_kept_and_another_target_is_refused() {
    let scene = scene("cornell-box");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("b");
    let o = out.to_str().unwrap();
    let bake = with(traced(&scene, o, "32", "2"), &["--noise", "0.05"]);
    let r = run(&bake);
    let (stdout, stderr) = text(&r);
    assert!(r.status.success(), "{stderr}");
    assert!(
        stdout.contains("noise (--noise 0.05): relative error"),
        "{stdout}"
    );
    let m = Manifest::read(&out).unwrap();
    assert_eq!(m.sampling.noise, Some(0.05));
    for e in &m.images {
        let report = e
            .noise
            .unwrap_or_else(|| panic!("{} has no report", e.file));
        assert!(
            stderr.contains(&format!("{}: relative error", e.file)),
            "{stderr}"
        );
        assert!(report.pixels > 0 && report.mean_spp >= 2.0, "{report:?}");
        assert!(report.at_limit.is_some_and(|s| (0.0..=1.0).contains(&s)));
        let kept = rangewalk::bake::sampling::read_report(&out.join(&e.file));
        assert_eq!(kept, Some(report));
    }
    let r = run(&["bake", "--status", o]);
    assert!(text(&r)
        .0
        .contains("noise of the done images: relative error"));

    let r = run(&with(traced(&scene, o, "32", "2"), &["--noise", "0.02"]));
    let err = text(&r).1;
    assert!(
        !r.status.success() && err.contains("--noise 0.05, not --noise 0.02"),
        "{err}"
    );
    let r = run(&with(bake.clone(), &["--max-spp", "32"]));
    assert!(r.status.success(), "{}", text(&r).1);
    let done = format!("0 rendered, {} already done", m.images.len());
    assert!(text(&r).0.contains(&done), "{}", text(&r).0);
}

/// `rangewalk bake` of the Cornell box with traced indirect light (no
/// radiosity to solve) into `out`.
fn traced<'a>(scene: &'a str, out: &'a str, size: &'a str, spp: &'a str) -> Vec<&'a str> {
    vec![
        "bake",
        scene,
        "--quality",
        "0.3",
        "--out",
        out,
        "--size",
        size,
        "--spp",
        spp,
        "--backend",
        "bvh",
        "--indirect",
        "path",
    ]
}

fn with<'a>(mut a: Vec<&'a str>, extra: &[&'a str]) -> Vec<&'a str> {
    a.extend_from_slice(extra);
    a
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn two_bakes_with_other_settings_on_one_empty_folder_make_one_bake_and_one_error() {
    let scene = scene("cornell-box");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("b");
    let o = out.to_str().unwrap();
    let runs: Vec<(&str, Child)> = ["2", "3"]
        .into_iter()
        .map(|spp| {
            let child = Command::new(env!("CARGO_BIN_EXE_rangewalk"))
                .args(traced(&scene, o, "32", spp))
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .expect("start rangewalk");
            (spp, child)
        })
        .collect();
    let ends: Vec<(&str, Output)> = runs
        .into_iter()
        .map(|(spp, c)| (spp, c.wait_with_output().unwrap()))
        .collect();
    let won: Vec<&str> = ends
        .iter()
        .filter(|(_, e)| e.status.success())
        .map(|(spp, _)| *spp)
        .collect();
    assert_eq!(
        won.len(),
        1,
        "{:?}",
        ends.iter().map(|(_, e)| text(e)).collect::<Vec<_>>()
    );
    let (_, lost) = ends.iter().find(|(spp, _)| *spp != won[0]).unwrap();
    let err = text(lost).1;
    assert!(
        err.contains("other settings") && err.contains("--spp"),
        "{err}"
    );
    let m = Manifest::read(&out).unwrap();
    assert_eq!(m.settings.spp.to_string(), won[0]);
    assert!(m.complete);
}

#[test]
fn a_running_bake_is_named_to_every_run_in_its_way_and_its_leftovers_removed_after() {
    let scene = scene("cornell-box");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("b");
    let o = out.to_str().unwrap();
    // Slow enough to be still rendering when the others have been refused.
    let slow = traced(&scene, o, "48", "2048");
    let mut first = spawn(&slow);
    let pid = format!("process {} ", first.id());
    let start = Instant::now();
    while !out.join("manifest.json").exists() {
        assert!(first.try_wait().unwrap().is_none(), "the first bake ended");
        assert!(start.elapsed() < Duration::from_secs(120), "no manifest");
        std::thread::sleep(Duration::from_millis(5));
    }
    // A second full bake, a shard of the same bake, a bake with other
    // settings, and finishing: each refused, naming the first bake.
    for (a, needle) in [
        (slow.clone(), "in use"),
        (with(slow.clone(), &["--shard", "1/2"]), "in use"),
        (traced(&scene, o, "48", "4"), "--spp 2048, not 4"),
        (vec!["bake", "--finish", o], "in use"),
    ] {
        let r = run(&a);
        let err = text(&r).1;
        assert!(
            !r.status.success() && err.contains(needle) && err.contains(&pid),
            "{a:?}: {err}"
        );
    }
    let status = text(&run(&["bake", "--status", o])).0;
    assert!(
        status.contains(&format!("running: {pid}")) && !status.contains("bake complete"),
        "{status}"
    );
    assert!(
        first.try_wait().unwrap().is_none(),
        "the first bake ended before the others were tried"
    );
    first.kill().unwrap();
    first.wait().unwrap();

    // What a run killed while writing leaves: removed by the next run,
    // which says so; nothing else is touched.
    let leftovers = [
        out.join("images").join(".v000-t000.exr.4242-0.partial"),
        out.join("images")
            .join(".v000-t000.exr.fnv1a64.4242.17.partial"),
        out.join(".manifest.json.4242.18.partial"),
    ];
    for p in &leftovers {
        std::fs::write(p, b"half").unwrap();
    }
    let prepared = run(&with(slow.clone(), &["--prepare"]));
    let (said, err) = text(&prepared);
    assert!(prepared.status.success(), "{err}");
    assert!(
        said.contains("removed 3 temporary files left by a stopped run"),
        "{said}"
    );
    for p in &leftovers {
        assert!(!p.exists(), "{} is still there", p.display());
    }
    assert!(out.join("manifest.json").exists());
}

#[test]
fn a_resume_with_other_planning_settings_is_refused_saying_which() {
    let scene = scene("cornell-box");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("b");
    let o = out.to_str().unwrap();
    let base = traced(&scene, o, "32", "1");
    let r = run(&base);
    assert!(r.status.success(), "{}", text(&r).1);
    let m = Manifest::read(&out).unwrap();
    assert_eq!(m.settings.planning.resolution, None);
    let side = m.plan.resolution.to_string();
    let other_side = (side.parse::<u32>().unwrap() + 16).to_string();
    let refusals = [
        (
            vec!["--view-fitness", "coverage"],
            "--view-fitness ids, not coverage",
        ),
        (vec!["--master-list"], "not --master-list"),
        (
            vec!["--resolution", &other_side],
            &*format!("--resolution {side}, not {other_side}"),
        ),
    ];
    for (extra, needle) in &refusals {
        let r = run(&with(base.clone(), extra));
        let err = text(&r).1;
        assert!(
            !r.status.success() && err.contains(needle),
            "{extra:?}: {err}"
        );
    }
    // Naming the default is the same plan.
    let r = run(&with(base.clone(), &["--resolution", &side]));
    assert!(r.status.success(), "{}", text(&r).1);

    // A bake of the previous manifest version (no planning settings) is
    // judged by what its plan recorded.
    let path = out.join("manifest.json");
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    m["version"] = 2.into();
    m["settings"].as_object_mut().unwrap().remove("planning");
    std::fs::write(&path, serde_json::to_string(&m).unwrap()).unwrap();
    let r = run(&with(base.clone(), &["--view-fitness", "coverage"]));
    let err = text(&r).1;
    assert!(
        !r.status.success() && err.contains("--view-fitness ids, not coverage"),
        "{err}"
    );
    let r = run(&base);
    assert!(r.status.success(), "{}", text(&r).1);
    m["version"] = 1.into();
    std::fs::write(&path, serde_json::to_string(&m).unwrap()).unwrap();
    let err = text(&run(&base)).1;
    assert!(
        err.contains("`version` is 1") && err.contains("bake it again"),
        "{err}"
    );
}

#[test]
fn status_and_bake_never_call_a_bake_with_a_missing_image_complete() {
    let scene = scene("cornell-box");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("b");
    let o = out.to_str().unwrap();
    let base = traced(&scene, o, "32", "1");
    let r = run(&base);
    assert!(r.status.success(), "{}", text(&r).1);
    let m = Manifest::read(&out).unwrap();
    assert!(m.complete);
    let total = m.images.len();
    // Image 0 is shard 0/2's: gone after the bake was completed.
    std::fs::remove_file(out.join(&m.images[0].file)).unwrap();
    let status = text(&run(&["bake", "--status", o])).0;
    assert!(
        status.contains(&format!("{} of {total} images done", total - 1))
            && status.contains("went missing")
            && !status.contains("bake complete"),
        "{status}"
    );
    // The other shard finds its own images and says the bake is not
    // complete.
    let (said, err) = text(&run(&with(base.clone(), &["--shard", "1/2"])));
    assert!(
        said.contains("bake not complete") && !said.contains("bake complete:"),
        "{said}{err}"
    );
    // Rendered again, it is complete, and says so everywhere.
    let (said, _) = text(&run(&base));
    assert!(
        said.contains("1 rendered") && said.contains("bake complete:"),
        "{said}"
    );
    let status = text(&run(&["bake", "--status", o])).0;
    assert!(status.contains("bake complete"), "{status}");
}

/// A bake says how much of its bases' pixels its windows leave out,
/// `--whole-bases` keeps them whole and says so, and resuming a bake with
/// the other choice is refused naming the option.
#[test]
fn a_bake_says_what_its_windows_leave_out_and_whole_bases_keep_everything() {
    let scene = scene("cornell-box");
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    let (a_, b_) = (a.to_str().unwrap(), b.to_str().unwrap());
    let partial = with(traced(&scene, a_, "384", "1"), &["--noise", "off"]);
    let r = run(&partial);
    let (stdout, stderr) = text(&r);
    assert!(r.status.success(), "{stderr}");
    let m = Manifest::read(&a).unwrap();
    let views = m.plan.views.len();
    assert!(
        m.windows.iter().all(|w| !w.is_whole(384)),
        "{:?}",
        m.windows
    );
    let all = (384 * 384 * views) as f64;
    let kept: u64 = m.windows.iter().map(|w| w.pixels()).sum();
    let line = stdout
        .lines()
        .find(|l| l.starts_with("base windows:"))
        .unwrap_or_else(|| panic!("no line on the windows: {stdout}"));
    for want in [
        format!("{views} of {views} views"),
        format!(
            "left out: {:.1}% of the base pixels",
            100.0 * (1.0 - kept as f64 / all)
        ),
    ] {
        assert!(line.contains(&want), "`{want}` not in: {line}");
    }
    let whole = with(
        traced(&scene, b_, "384", "1"),
        &["--noise", "off", "--whole-bases"],
    );
    let r = run(&whole);
    let (stdout, stderr) = text(&r);
    assert!(r.status.success(), "{stderr}");
    assert!(
        stdout.contains("base windows: every base keeps its whole 384x384 image"),
        "{stdout}"
    );
    assert!(Manifest::read(&b)
        .unwrap()
        .windows
        .iter()
        .all(|w| w.is_whole(384)));
    let again = with(partial.clone(), &["--whole-bases"]);
    let r = run(&again);
    let (_, stderr) = text(&r);
    assert!(
        !r.status.success() && stderr.contains("--whole-bases"),
        "{stderr}"
    );
}
