//! The `rangewalk` binary as a user meets it: outputs, figures and errors.

use std::path::Path;
use std::process::{Command, Output};

mod common;
use common::{rangewalk, scene_arg};

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs `args`, which must fail with `needle` in the message.
fn fails_with(args: &[&str], needle: &str) {
    let o = rangewalk(args);
    assert!(!o.status.success(), "{args:?} succeeded");
    assert!(
        stderr(&o).contains(needle),
        "{args:?}: `{needle}` not in {}",
        stderr(&o)
    );
}

fn render_args<'a>(scene: &'a str, out: &'a str) -> Vec<&'a str> {
    with(scene, out, &[])
}

/// `render` arguments with some options' values replaced.
fn with<'a>(scene: &'a str, out: &'a str, changes: &[(&'a str, &'a str)]) -> Vec<&'a str> {
    let mut args = vec![
        "render", scene, "--time", "0.5", "--spp", "4", "--size", "16x16", "--out", out,
    ];
    for &(flag, value) in changes {
        match args.iter().position(|a| *a == flag) {
            Some(i) => args[i + 1] = value,
            None => args.extend([flag, value]),
        }
    }
    args
}

#[test]
fn render_writes_a_range_image_and_reports_throughput() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cb.exr");
    let png = dir.path().join("cb.png");
    let cb = scene_arg("cornell-box");
    let mut args = render_args(&cb, out.to_str().unwrap());
    args.extend(["--backend", "bvh", "--preview", png.to_str().unwrap()]);
    let o = rangewalk(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("samples/s") && stdout.contains("rays/s"),
        "{stdout}"
    );
    let img = rangewalk::image::read_exr(&out).unwrap();
    assert_eq!((img.width, img.height), (16, 16));
    assert!((img.meta.time - 0.5).abs() < 1e-6);
    assert!(img
        .radiance
        .iter()
        .all(|c| c.is_finite() && c.min_element() >= 0.0));
    assert!(
        img.radiance.iter().any(|c| c.max_element() > 0.0),
        "the Cornell box renders black"
    );
    // Every pixel of the camera `main` sees the inside of the box.
    assert!(
        img.object_id.iter().all(|&id| id < 8),
        "{:?}",
        img.object_id
    );
    assert!(img.distance.iter().all(|&d| d > 800.0 && d < 2000.0));
    assert!(png.is_file());
}

#[test]
fn bad_inputs_fail_with_a_message_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.exr");
    let out_s = out.to_str().unwrap();
    let cb = scene_arg("cornell-box");
    let missing = dir.path().join("nope.toml");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (render_args(missing.to_str().unwrap(), out_s), "nope.toml"),
        (with(&cb, out_s, &[("--camera", "side")]), "side"),
        (with(&cb, out_s, &[("--size", "0x16")]), "0x16"),
        (with(&cb, out_s, &[("--spp", "0")]), "spp"),
        (with(&cb, out_s, &[("--time", "NaN")]), "time"),
    ];
    for (args, needle) in cases {
        fails_with(&args, needle);
        assert!(!out.exists(), "{args:?} left {}", out.display());
    }
    // An output folder that does not exist: the error names the file.
    let deep = dir.path().join("no/such/dir/x.exr");
    let o = rangewalk(&render_args(&cb, deep.to_str().unwrap()));
    assert!(!o.status.success());
    assert!(stderr(&o).contains("x.exr"), "{}", stderr(&o));
}

/// Outputs that cannot be written are found before any work: checked
/// before the scene is even read (so a missing scene is not what fails),
/// and an extension that is not the format written is an error.
#[test]
fn outputs_are_checked_before_the_work_starts() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.toml");
    let missing = missing.to_str().unwrap();
    let cb = scene_arg("cornell-box");
    let exr = dir.path().join("x.exr");
    let exr = exr.to_str().unwrap();
    let txt = dir.path().join("x.txt");
    let png = dir.path().join("p.png");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            render_args(missing, "/nonexistent/dir/x.exr"),
            "folder /nonexistent/dir does not exist",
        ),
        (render_args(missing, txt.to_str().unwrap()), "`.txt`"),
        (
            with(missing, exr, &[("--preview", "/nonexistent/p.png")]),
            "--preview",
        ),
        (with(missing, exr, &[("--preview", exr)]), "expected .png"),
        (
            with(missing, exr, &[("--hdr", png.to_str().unwrap())]),
            "--hdr",
        ),
    ];
    for (args, needle) in cases {
        fails_with(&args, needle);
    }
    // The same outputs with the real scene: nothing is left behind.
    let o = rangewalk(&render_args(&cb, txt.to_str().unwrap()));
    assert!(!o.status.success() && !txt.exists());
    assert!(std::fs::read_dir(dir.path()).unwrap().next().is_none());
}

/// Every command's outputs, files and folders alike, are checked before
/// its inputs are even read: each case names an input that does not
/// exist, so only the output check can produce the message asked for,
/// and nothing may be left behind.
#[test]
fn every_command_checks_its_outputs_first() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let (scene, bake) = (p("nope.toml"), p("no-bake"));
    let file = p("a-file");
    std::fs::write(&file, "").unwrap();
    let (txt, x, png_as_exr, plan_txt) = (p("x.txt"), p("x.exr"), p("p.exr"), p("plan.txt"));
    // Output folders are made with their parents; one under a file cannot be.
    let missing = format!("{file}/dir/out");
    let missing = missing.as_str();
    let blocked = "a-file is a file, not a folder";
    let gone = "folder /nonexistent/dir does not exist";
    let exr = "/nonexistent/dir/x.exr";
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["synth", &bake, "--time", "0", "--out", exr], gone),
        (vec!["synth", &bake, "--time", "0", "--out", &txt], "`.txt`"),
        (
            vec![
                "synth",
                &bake,
                "--time",
                "0",
                "--out",
                &x,
                "--preview",
                &png_as_exr,
            ],
            "--preview",
        ),
        (
            vec!["walk", &bake, "--path", "walk", "--out", missing],
            blocked,
        ),
        (
            vec!["walk", &bake, "--path", "walk", "--out", &file],
            "not a folder",
        ),
        (
            vec!["bake", &scene, "--quality", "0.5", "--out", missing],
            blocked,
        ),
        (
            vec![
                "bake",
                &scene,
                "--quality",
                "0.5",
                "--out",
                "/proc/rangewalk-bake",
            ],
            "cannot create files in /proc",
        ),
        (vec!["radiosity", &scene, "--out", missing], blocked),
        (
            vec!["export", &scene, "--format", "mitsuba", "--out", missing],
            blocked,
        ),
        (
            vec!["plan", &scene, "--quality", "0.5", "--out", &plan_txt],
            "expected .json",
        ),
        (
            vec![
                "plan",
                &scene,
                "--quality",
                "0.5",
                "--out",
                "/nonexistent/dir/p.json",
            ],
            gone,
        ),
        (
            vec![
                "slurm",
                &scene,
                "--quality",
                "0.5",
                "--tasks",
                "2",
                "--out",
                missing,
            ],
            blocked,
        ),
        (
            vec!["experiment", "indirect", &scene, "--out", missing],
            blocked,
        ),
        (
            vec!["experiment", "views", &scene, "--out", missing],
            blocked,
        ),
        (
            vec!["experiment", "motion", &scene, "--out", missing],
            blocked,
        ),
        (
            vec![
                "experiment",
                "walkthrough",
                &scene,
                "--path",
                "walk",
                "--out",
                missing,
            ],
            blocked,
        ),
        (
            vec!["view", &bake, "--screenshot", "/nonexistent/dir/s.png"],
            gone,
        ),
        (vec!["view", &bake, "--record", missing], blocked),
        (
            vec![
                "render",
                &scene,
                "--out",
                &x,
                "--indirect",
                "radiosity",
                "--bake",
                missing,
            ],
            blocked,
        ),
    ];
    for (args, needle) in &cases {
        fails_with(args, needle);
    }
    assert!(!Path::new("/nonexistent").exists());
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().flatten().collect();
    assert_eq!(left.len(), 1, "{left:?}");
}

/// A size whose image would not fit in memory is refused while parsing.
#[test]
fn absurd_sizes_are_refused_before_any_allocation() {
    let cb = scene_arg("cornell-box");
    for (size, why) in [
        ("100000x100000", "above the 32768 pixels"),
        ("32768x32768", "(8192x8192)"),
        ("0x16", "positive integers"),
    ] {
        let o = rangewalk(&with(&cb, "/tmp/never.exr", &[("--size", size)]));
        assert!(!o.status.success(), "{size} accepted");
        let err = stderr(&o);
        assert!(err.contains(size) && err.contains(why), "{size}: {err}");
    }
}

#[test]
fn info_says_which_stages_a_scene_needs() {
    let o = rangewalk(&["info", &scene_arg("cornell-box")]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(
        s.contains("8 objects") && s.contains("no specular rays"),
        "{s}"
    );
    assert!(s.contains("animated over [0, 1] s"), "{s}");
    let o = rangewalk(&["info", &scene_arg("furnace")]);
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(s.contains("static scene: one time sample"), "{s}");
    let o = rangewalk(&["info", &scene_arg("glossy-sun")]);
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(!s.contains("no specular rays") && s.contains("sun"), "{s}");
}

#[test]
fn export_writes_a_mitsuba_scene() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("mts");
    let o = rangewalk(&[
        "export",
        &scene_arg("cornell-box"),
        "--time",
        "1",
        "--size",
        "32x32",
        "--spp",
        "16",
        "--format",
        "mitsuba",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let xml = std::fs::read_to_string(Path::new(&out).join("scene.xml")).unwrap();
    assert!(
        xml.contains("<scene") && xml.contains("area") && xml.contains("\"spp\""),
        "{xml}"
    );
}

/// Subpixels outside what synthesis takes are refused by every experiment
/// before it bakes or writes anything.
#[test]
fn experiments_refuse_subpixels_out_of_range_before_any_work() {
    let cb = scene_arg("cornell-box");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let out = out.to_str().unwrap();
    for kind in ["views", "motion"] {
        for bad in ["0", "5"] {
            fails_with(
                &[
                    "experiment",
                    kind,
                    &cb,
                    "--supersample",
                    bad,
                    "--no-flip",
                    "--out",
                    out,
                ],
                &format!("--supersample {bad} must lie in 1..=4"),
            );
        }
    }
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().flatten().collect();
    assert!(left.is_empty(), "{left:?}");
}

// Messages that say what is wrong and what to do (issue 49).

/// A tmpfs of `size` mounted on a fresh folder, unmounted when dropped.
/// Mounting needs root, as these tests run here and in CI: a machine that
/// cannot mount fails the test rather than skips it.
struct TinyDisk {
    dir: tempfile::TempDir,
}

impl TinyDisk {
    fn new(size: &str) -> Self {
        let dir = tempfile::tempdir().unwrap();
        let o = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(dir.path())
            .output()
            .expect("run mount");
        assert!(
            o.status.success(),
            "cannot mount a tmpfs (the test needs root): {}",
            stderr(&o)
        );
        Self { dir }
    }

    fn path(&self, name: &str) -> String {
        self.dir.path().join(name).to_string_lossy().into_owned()
    }

    /// Fills the disk to the last byte.
    fn fill(&self) {
        let filler = vec![0u8; 1 << 20];
        assert!(std::fs::write(self.path("filler"), filler).is_err());
    }
}

impl Drop for TinyDisk {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(self.dir.path()).status();
    }
}

/// Every image format, written to a full disk, says the disk is full and
/// names the file, and leaves nothing under its name.
#[test]
fn a_full_disk_is_named_as_such() {
    let cb = scene_arg("cornell-box");
    let disk = TinyDisk::new("16k");
    // A 64x64 range image is about 64 KiB.
    let big = disk.path("big.exr");
    let args = with(&cb, &big, &[("--spp", "1"), ("--size", "64x64")]);
    fails_with(&args, "no space left on the device (the disk is full)");
    fails_with(&args, "big.exr");
    assert!(!Path::new(&big).exists());
    disk.fill();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.exr");
    let out = out.to_str().unwrap();
    for (flag, name) in [
        ("--out", "x.exr"),
        ("--preview", "p.png"),
        ("--hdr", "p.hdr"),
    ] {
        let file = disk.path(name);
        let args = with(&cb, out, &[("--spp", "1"), (flag, &file)]);
        let o = rangewalk(&args);
        let err = stderr(&o);
        assert!(!o.status.success(), "{flag}: {err}");
        assert!(
            err.contains("the disk is full") && err.contains(name),
            "{flag}: {err}"
        );
        assert!(!Path::new(&file).exists(), "{flag}");
    }
}

/// A folder holding `scene.toml` (the given text) and `quad.obj`, a unit
/// square facing -z.
fn small_scene(toml: &str) -> (tempfile::TempDir, String) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("quad.obj"),
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n",
    )
    .unwrap();
    let path = dir.path().join("scene.toml");
    std::fs::write(&path, toml).unwrap();
    (dir, path.to_string_lossy().into_owned())
}

const SMALL: &str = r#"
[[materials]]
name = "grey"
type = "diffuse"
reflectance = [0.5, 0.5, 0.5]

[[objects]]
name = "quad"
mesh = "quad.obj"
material = "grey"

[[cameras]]
name = "main"
position = [0.5, 0.5, -2]
look_at = [0.5, 0.5, 0]
vfov = 40
"#;

/// Runs `args`, which must fail with every needle in the message without
/// opening `fifo` (if given) for reading: while it runs, a writer knocks
/// on the FIFO without blocking; a reader that answers (one blocked in
/// `open` counts) is let go with an end of file and fails the test.
fn fails_without_opening(args: &[&str], needles: &[&str], fifo: Option<&Path>) {
    use std::os::unix::fs::OpenOptionsExt;
    use std::sync::atomic::{AtomicBool, Ordering};
    let done = AtomicBool::new(false);
    let (o, opened) = std::thread::scope(|s| {
        let knock = s.spawn(|| {
            let Some(fifo) = fifo else { return false };
            while !done.load(Ordering::Relaxed) {
                match std::fs::OpenOptions::new()
                    .write(true)
                    .custom_flags(libc::O_NONBLOCK)
                    .open(fifo)
                {
                    Ok(_) => return true,
                    Err(e) if e.raw_os_error() == Some(libc::ENXIO) => {}
                    Err(e) => panic!("knocking on {}: {e}", fifo.display()),
                }
                std::thread::sleep(std::time::Duration::from_millis(5));
            }
            false
        });
        let o = rangewalk(args);
        done.store(true, Ordering::Relaxed);
        (o, knock.join().unwrap())
    });
    assert!(!opened, "{args:?} opened the FIFO for reading");
    assert!(!o.status.success(), "{args:?} succeeded");
    let err = stderr(&o);
    for n in needles {
        assert!(err.contains(n), "{args:?}: `{n}` not in {err}");
    }
}

fn mkfifo(path: &Path) {
    let o = Command::new("mkfifo")
        .arg(path)
        .output()
        .expect("run mkfifo");
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A mesh, texture or scene file that is a folder, a FIFO or a symlink
/// loop is called what it is, naming the scene file and field, and a FIFO
/// is never opened (that would block).
#[test]
fn input_files_that_are_not_files_are_called_what_they_are() {
    type Make = fn(&Path);
    let kinds: [(Make, &str, bool); 3] = [
        (|p| std::fs::create_dir(p).unwrap(), "is a folder", false),
        (mkfifo, "is a FIFO (named pipe), not a regular file", true),
        (
            |p| std::os::unix::fs::symlink(p.file_name().unwrap(), p).unwrap(),
            "is a symlink loop",
            false,
        ),
    ];
    for (make, words, fifo) in kinds {
        let knock = |p: &Path| fifo.then(|| p.to_path_buf());
        // As a mesh.
        let (dir, scene) = small_scene(&SMALL.replace("quad.obj", "odd.obj"));
        let odd = dir.path().join("odd.obj");
        make(&odd);
        fails_without_opening(
            &["info", &scene],
            &[words, "scene.toml:", "object `quad`", "`mesh`", "odd.obj"],
            knock(&odd).as_deref(),
        );
        // As a texture.
        let textured = SMALL.replace(
            "reflectance = [0.5, 0.5, 0.5]",
            "reflectance = [0.5, 0.5, 0.5]\ntexture = \"odd.png\"",
        );
        let (dir, scene) = small_scene(&textured);
        let odd = dir.path().join("odd.png");
        make(&odd);
        fails_without_opening(
            &["info", &scene],
            &[
                words,
                "scene.toml:",
                "material `grey`",
                "`texture`",
                "odd.png",
            ],
            knock(&odd).as_deref(),
        );
        // As the scene file.
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("scene.toml");
        make(&scene);
        fails_without_opening(
            &["info", scene.to_str().unwrap()],
            &[words, "scene.toml"],
            knock(&scene).as_deref(),
        );
    }
}

/// An object without a triangle is refused, naming it and its mesh, even
/// beside objects that have triangles.
#[test]
fn an_object_without_triangles_is_refused() {
    let two = format!(
        "{SMALL}\n[[objects]]\nname = \"ghost\"\nmesh = \"points.obj\"\nmaterial = \"grey\"\n"
    );
    let (dir, scene) = small_scene(&two);
    std::fs::write(dir.path().join("points.obj"), "v 0 0 0\nv 1 0 0\np 1 2\n").unwrap();
    fails_with(&["info", &scene], "object `ghost` has no triangles");
    fails_with(&["info", &scene], "points.obj has no faces");
    // Faces that all have zero area.
    std::fs::write(
        dir.path().join("points.obj"),
        "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n",
    )
    .unwrap();
    fails_with(&["info", &scene], "the 1 triangle(s) of");
    fails_with(&["info", &scene], "all have zero area");
}

/// A transform that carries an object out of range is refused when the
/// scene is read, naming the scene file's line, the object and the field,
/// not later as a camera of NaNs.
#[test]
fn transforms_out_of_range_name_the_object_and_field() {
    for (field, needles) in [
        (
            "translate = [1e38, 0, 0]",
            ["`translate` [1e38, 0.0, 0.0]", "beyond"],
        ),
        ("scale = 1e38", ["at time 1 the object reaches", "`scale`"]),
    ] {
        let keys = format!(
            "\n[[objects.keyframes]]\ntime = 0\n[[objects.keyframes]]\ntime = 1\n{field}\n"
        );
        let moved = SMALL.replace(
            "material = \"grey\"\n",
            &format!("material = \"grey\"{keys}"),
        );
        let (_dir, scene) = small_scene(&moved);
        for n in ["scene.toml:", "object `quad` keyframe"]
            .iter()
            .chain(&needles)
        {
            fails_with(&["info", &scene], n);
        }
    }
}

/// A damaged radiosity store says that deleting it repairs it, and it does.
#[test]
fn a_damaged_radiosity_store_says_how_to_repair_it() {
    let furnace = scene_arg("furnace");
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("rad");
    let store_s = store.to_str().unwrap();
    let o = rangewalk(&["radiosity", &furnace, "--quality", "0", "--out", store_s]);
    assert!(o.status.success(), "{}", stderr(&o));
    let irr = store.join("irradiance.bin");
    let mut bytes = std::fs::read(&irr).unwrap();
    bytes[0] ^= 1;
    std::fs::write(&irr, bytes).unwrap();
    let out = dir.path().join("x.exr");
    let out = out.to_str().unwrap();
    let args = with(
        &furnace,
        out,
        &[
            ("--time", "0"),
            ("--spp", "1"),
            ("--indirect", "radiosity"),
            ("--bake", store_s),
        ],
    );
    fails_with(&args, &format!("delete {store_s} to repair it"));
    std::fs::remove_dir_all(&store).unwrap();
    let o = rangewalk(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(store.join("irradiance.bin").is_file());
}

/// A negative `--time` reaches the scene's check (clap would take `-1`
/// for a flag), and a time outside an animated scene's animation is an
/// error naming the value and the span; a static scene takes any time.
#[test]
fn times_outside_the_animation_are_refused_naming_the_span() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.exr");
    let out = out.to_str().unwrap();
    let cb = scene_arg("cornell-box");
    for t in ["-1", "1.5"] {
        let args = with(
            &cb,
            out,
            &[("--time", t), ("--spp", "1"), ("--size", "8x8")],
        );
        fails_with(
            &args,
            &format!("--time: time {t} s lies outside the animation of"),
        );
        fails_with(&args, "[0, 1] s");
        assert!(!Path::new(out).exists());
    }
    let static_scene = scene_arg("furnace");
    let args = with(
        &static_scene,
        out,
        &[("--time", "-1"), ("--spp", "1"), ("--size", "8x8")],
    );
    let o = rangewalk(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    // `synth` takes a negative time as a value too: what fails is the
    // missing bake.
    let bake = dir.path().join("no-bake");
    let o = rangewalk(&[
        "synth",
        bake.to_str().unwrap(),
        "--time",
        "-1",
        "--out",
        out,
    ]);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert!(
        !err.contains("unexpected argument") && err.contains("no-bake"),
        "{err}"
    );
}

/// Base images too small to show a scene, or too large to read back, are
/// refused before any work, naming the size and the range.
#[test]
fn base_image_sizes_outside_the_range_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bake");
    let out = out.to_str().unwrap();
    let cb = scene_arg("cornell-box");
    for (size, needle) in [
        ("7", "--size 7 is below the smallest base image side, 16"),
        ("0", "--size 0 is below the smallest base image side, 16"),
        (
            "9000",
            "--size 9000 is above the largest base image side, 8192",
        ),
    ] {
        fails_with(
            &[
                "bake",
                &cb,
                "--quality",
                "0.1",
                "--out",
                out,
                "--size",
                size,
            ],
            needle,
        );
    }
    fails_with(
        &[
            "bake",
            &cb,
            "--quality",
            "0.1",
            "--out",
            out,
            "--frame-size",
            "8192x8192",
        ],
        "above the largest side, 8192",
    );
    assert!(!Path::new(out).exists());
}

/// `compare` measures an image only against a reference of its size,
/// projection and camera: a 64x32 image against a 32x64 one has as many
/// pixels and gave an LRMS of 20.8; a fisheye against a perspective image,
/// or another camera's, compared pixels that look elsewhere. Each is an
/// error naming both files; another scene time is a warning.
#[test]
fn compare_refuses_images_of_other_sizes_projections_and_cameras() {
    use glam::Vec3;
    use rangewalk::camera::{Camera, Projection};
    use rangewalk::image::{RangeImage, RangeMeta};

    let dir = tempfile::tempdir().unwrap();
    let perspective = Projection::Perspective { vfov_deg: 40.0 };
    let (at, to) = (
        Vec3::new(278.0, 273.0, -800.0),
        Vec3::new(278.0, 273.0, 0.0),
    );
    let write = |name: &str, projection, position: Vec3, (w, h), time: f32| {
        let camera = Camera::look_at(position, to, Vec3::Y, projection, w, h).unwrap();
        let mut img = RangeImage::empty(RangeMeta {
            camera,
            time,
            scene: name.into(),
        });
        for (i, c) in img.radiance.iter_mut().enumerate() {
            *c = Vec3::splat(1.0 + (i % 7) as f32);
        }
        img.distance.fill(800.0);
        let path = dir.path().join(name);
        rangewalk::image::write_exr(&path, &img).unwrap();
        path.to_str().unwrap().to_owned()
    };
    let reference = write("ref.exr", perspective, at, (64, 32), 0.5);
    let same = write("same.exr", perspective, at, (64, 32), 0.5);
    let tall = write("tall.exr", perspective, at, (32, 64), 0.5);
    let fisheye = write("fisheye.exr", Projection::Fisheye, at, (64, 32), 0.5);
    let wider = write(
        "wider.exr",
        Projection::Perspective { vfov_deg: 60.0 },
        at,
        (64, 32),
        0.5,
    );
    let moved = write("moved.exr", perspective, at + Vec3::X * 10.0, (64, 32), 0.5);
    let later = write("later.exr", perspective, at, (64, 32), 0.75);

    for (image, needles) in [
        (&tall, vec!["tall.exr against", "ref.exr", "32x64", "64x32"]),
        (
            &fisheye,
            vec!["fisheye.exr against", "ref.exr", "a fisheye view"],
        ),
        (
            &wider,
            vec!["wider.exr against", "60° vertical", "40° vertical"],
        ),
        (&moved, vec!["moved.exr against", "ref.exr", "camera is at"]),
    ] {
        let o = rangewalk(&["compare", &reference, image]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{image}: {err}");
        assert!(
            String::from_utf8_lossy(&o.stdout).is_empty(),
            "{image}: an error was printed"
        );
        for needle in needles {
            assert!(err.contains(needle), "{image}: `{needle}` not in {err}");
        }
    }
    let o = rangewalk(&["compare", &reference, &same, &later]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("same.exr: LRMS 0.0000"), "{out}");
    assert!(out.contains("later.exr: LRMS 0.0000"), "{out}");
    let err = stderr(&o);
    assert!(
        err.contains("warning: ") && err.contains("later.exr") && err.contains("t = 0.75 s"),
        "{err}"
    );
    assert!(!err.contains("same.exr"), "{err}");
}
