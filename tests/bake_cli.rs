//! `rangewalk bake` as a user runs it: killed at any moment and started
//! again it ends with the images of an uninterrupted bake; its errors name
//! what is wrong.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output};
use std::time::{Duration, Instant};

use rangewalk::bake::Manifest;
use rangewalk::image::exr_content_hash;

fn scene(name: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
        .join("scene.toml")
        .to_string_lossy()
        .into_owned()
}

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

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rangewalk"))
        .args(args)
        .output()
        .expect("run rangewalk")
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
            name.starts_with('.') || name.ends_with(".exr") || name.ends_with(".fnv1a64"),
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
    // A folder that holds something else is not written into.
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let r = run(&args(&scene, o));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("not a bake"), "{err}");
}
