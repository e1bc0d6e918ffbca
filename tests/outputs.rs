//! What the commands write, and what they never touch: an output folder
//! that holds anything the command did not write (the user's files, the
//! bake being read, the scene's folder) is refused and left as it was;
//! nothing is written into a bake; a command that fails (midway, or on a
//! full disk) leaves neither a half-written result under the final name
//! nor leftovers beside it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;

fn rangewalk(args: &[&str]) -> Output {
    common::command()
        .args(args)
        .env_remove("DISPLAY")
        .output()
        .expect("running rangewalk")
}

fn ok(o: &Output, what: &str) {
    assert!(
        o.status.success(),
        "{what} failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Fails unless `o` failed with a message holding `needle`.
fn fails_with(o: &Output, needle: &str) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "it succeeded; stderr:\n{err}");
    assert!(err.contains(needle), "no `{needle}` in:\n{err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// Every file under `dir` with its bytes, sorted: what must not change.
fn tree(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                out.push((p.clone(), Vec::new()));
                stack.push(p);
            } else {
                out.push((p.clone(), std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A copy of the Cornell box's folder (the scene may be damaged or
/// written into by a test) and a small bake of it (two views, two times,
/// 64² bases, 1 spp, traced indirect light).
fn scene_and_bake(root: &Path) -> (PathBuf, PathBuf) {
    let scene_dir = root.join("scene");
    std::fs::create_dir(&scene_dir).unwrap();
    for f in ["scene.toml", "cornell-box.obj"] {
        std::fs::copy(repo("scenes/cornell-box").join(f), scene_dir.join(f)).unwrap();
    }
    let bake = root.join("bake");
    let o = rangewalk(&[
        "bake",
        s(&scene_dir.join("scene.toml")),
        "--quality",
        "0.3",
        "--size",
        "64",
        "--spp",
        "1",
        "--indirect",
        "path",
        "--out",
        s(&bake),
    ]);
    ok(&o, "the test's bake");
    (scene_dir, bake)
}

fn walk(bake: &Path, out: &Path) -> Output {
    rangewalk(&[
        "walk",
        s(bake),
        "--path",
        "walk",
        "--size",
        "16x16",
        "--fps",
        "4",
        "--out",
        s(out),
    ])
}

#[test]
fn a_walk_replaces_only_a_walk_and_leaves_nothing_when_it_fails() {
    let root = tempfile::tempdir().unwrap();
    let (scene_dir, bake) = scene_and_bake(root.path());

    // A folder of the user's, the bake being read, the scene's folder: each
    // refused with a message naming what it holds, each left as it was.
    let mine = root.path().join("mine");
    std::fs::create_dir(&mine).unwrap();
    std::fs::write(mine.join("notes.txt"), "years of work").unwrap();
    std::fs::write(mine.join("frame-0000.exr"), "not a frame of ours").unwrap();
    for folder in [&mine, &bake, &scene_dir] {
        let before = tree(folder);
        let err = fails_with(&walk(&bake, folder), "refusing to replace");
        assert!(err.contains(s(folder)), "{err}");
        assert_eq!(tree(folder), before, "{} changed", folder.display());
    }
    // A `.partial` beside the output is held to the same rule.
    let out = root.path().join("walk");
    let partial = root.path().join("walk.partial");
    std::fs::create_dir(&partial).unwrap();
    std::fs::write(partial.join("draft.txt"), "mine too").unwrap();
    fails_with(&walk(&bake, &out), "draft.txt");
    assert_eq!(names(&partial), ["draft.txt"]);
    std::fs::remove_dir_all(&partial).unwrap();

    // A walk, then another over it: the second replaces the first.
    ok(&walk(&bake, &out), "the first walk");
    let first = tree(&out);
    assert!(names(&out).contains(&"frame-0004.exr".to_string()));
    ok(&walk(&bake, &out), "the walk over it");
    assert_eq!(
        names(&out),
        first
            .iter()
            .map(|(p, _)| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect::<Vec<_>>()
    );

    // A walk that fails midway (a base image's planes file, which frames
    // read, damaged after the bake, found when a frame first reads it)
    // keeps the earlier walk and leaves no partial folder.
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(bake.join("manifest.json")).unwrap()).unwrap();
    let last = manifest["images"].as_array().unwrap().last().unwrap()["file"]
        .as_str()
        .unwrap()
        .to_string();
    let victim = bake.join(format!("{last}.planes"));
    let bytes = std::fs::read(&victim).unwrap();
    std::fs::write(&victim, &bytes[..bytes.len() / 2]).unwrap();
    let before = tree(&out);
    fails_with(&walk(&bake, &out), &last);
    assert_eq!(tree(&out), before, "the earlier walk changed");
    assert_eq!(names(root.path()), ["bake", "mine", "scene", "walk"]);
}

#[test]
fn nothing_is_written_into_a_bake() {
    let root = tempfile::tempdir().unwrap();
    let (scene_dir, bake) = scene_and_bake(root.path());
    let scene = scene_dir.join("scene.toml");
    let before = tree(&bake);
    let image = bake.join("images").join(&names(&bake.join("images"))[0]);
    let (bake_s, scene_s) = (s(&bake), s(&scene));
    let frame = root.path().join("frame.exr");
    let preview = bake.join("preview.png");
    let manifest = bake.join("manifest.json");
    let new_image = bake.join("images").join("new.exr");
    let walk_out = bake.join("walk");
    let synth = ["synth", bake_s, "--time", "0.5", "--size", "16x16", "--out"];
    let runs: [Vec<&str>; 5] = [
        [&synth[..], &[s(&image)]].concat(),
        [&synth[..], &[s(&frame), "--preview", s(&preview)]].concat(),
        vec!["plan", scene_s, "--quality", "0.3", "--out", s(&manifest)],
        vec![
            "render",
            scene_s,
            "--size",
            "8x8",
            "--spp",
            "1",
            "--out",
            s(&new_image),
        ],
        vec!["walk", bake_s, "--path", "walk", "--out", s(&walk_out)],
    ];
    let store = bake.canonicalize().unwrap();
    for args in runs {
        let err = fails_with(&rangewalk(&args), "rangewalk store");
        assert!(err.contains(s(&store)), "{err}");
        assert_eq!(tree(&bake), before, "`{}` changed the bake", args.join(" "));
    }
    assert!(!root.path().join("frame.exr").exists());
}

/// A copy of the Cornell box with a last object whose material emits
/// from both sides, which a Mitsuba export refuses when it reaches it:
/// after the meshes of the other objects are written.
fn scene_that_fails_to_export(root: &Path) -> PathBuf {
    let dir = root.join("two-sided");
    std::fs::create_dir(&dir).unwrap();
    std::fs::copy(
        repo("scenes/cornell-box/cornell-box.obj"),
        dir.join("cornell-box.obj"),
    )
    .unwrap();
    let text = std::fs::read_to_string(repo("scenes/cornell-box/scene.toml")).unwrap()
        + "\n[[materials]]\nname = \"both\"\ntype = \"diffuse\"\nreflectance = [0.5, 0.5, 0.5]\n\
           emission = [1, 1, 1]\ntwo_sided_emission = true\n\n\
           [[objects]]\nname = \"panel\"\nmesh = \"cornell-box.obj\"\ngroup = \"light\"\n\
           material = \"both\"\n";
    std::fs::write(dir.join("scene.toml"), text).unwrap();
    dir.join("scene.toml")
}

fn export(scene: &Path, time: &str, out: &Path) -> Output {
    rangewalk(&[
        "export",
        s(scene),
        "--size",
        "8x8",
        "--time",
        time,
        "--format",
        "mitsuba",
        "--out",
        s(out),
    ])
}

#[test]
fn an_export_is_replaced_whole_or_not_at_all() {
    let root = tempfile::tempdir().unwrap();
    let out = root.path().join("mitsuba");
    let cornell = repo("scenes/cornell-box/scene.toml");
    ok(&export(&cornell, "0", &out), "the first export");
    let first = tree(&out);
    assert!(names(&out).contains(&"scene.xml".to_string()));

    // An export of another time that fails midway: the folder still holds
    // the first export, scene and meshes of one time, and nothing else.
    let failing = scene_that_fails_to_export(root.path());
    fails_with(&export(&failing, "1", &out), "both sides");
    assert_eq!(tree(&out), first, "the earlier export changed");
    assert_eq!(names(root.path()), ["mitsuba", "two-sided"]);

    // A whole export of that time replaces it.
    ok(&export(&cornell, "1", &out), "the second export");
    assert_ne!(tree(&out), first);

    // A folder of the user's is refused and left as it was.
    let mine = root.path().join("two-sided");
    let before = tree(&mine);
    fails_with(&export(&cornell, "0", &mine), "refusing to replace");
    assert_eq!(tree(&mine), before);
}

/// A 64 KiB tmpfs mounted on a folder of the test's, filled to its last
/// byte, and unmounted when dropped. Mounting needs root, which the
/// tests have here and in CI; without it the test fails, saying so.
struct FullDisk {
    dir: tempfile::TempDir,
}

impl FullDisk {
    fn new() -> FullDisk {
        let dir = tempfile::tempdir().unwrap();
        let o = Command::new("mount")
            .args(["-t", "tmpfs", "-o", "size=64k", "tmpfs", s(dir.path())])
            .output()
            .expect("running mount");
        assert!(
            o.status.success(),
            "mounting a tmpfs for a full disk (needs root): {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let disk = FullDisk { dir };
        // Filled until a write fails; a page more may be taken by metadata.
        let filler = disk.dir.path().join("filler");
        let o = Command::new("dd")
            .args(["if=/dev/zero", &format!("of={}", s(&filler)), "bs=4096"])
            .output()
            .unwrap();
        assert!(!o.status.success(), "the tmpfs did not fill");
        disk
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }
}

impl Drop for FullDisk {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(self.dir.path()).status();
    }
}

#[test]
fn a_full_disk_leaves_no_files_behind() {
    let disk = FullDisk::new();
    let cornell = repo("scenes/cornell-box/scene.toml");
    let o = rangewalk(&[
        "plan",
        s(&cornell),
        "--quality",
        "0.3",
        "--out",
        s(&disk.path().join("plan.json")),
    ]);
    fails_with(&o, "plan.json");
    assert_eq!(names(disk.path()), ["filler"]);

    fails_with(
        &export(&cornell, "0", &disk.path().join("mitsuba")),
        "mitsuba",
    );
    assert_eq!(names(disk.path()), ["filler"]);

    let o = rangewalk(&[
        "render",
        s(&cornell),
        "--size",
        "64x64",
        "--spp",
        "1",
        "--out",
        s(&disk.path().join("frame.exr")),
    ]);
    fails_with(&o, "frame.exr");
    assert_eq!(names(disk.path()), ["filler"]);
}
