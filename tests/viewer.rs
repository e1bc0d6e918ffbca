//! `rangewalk view` in a real window under Xvfb: a path played for 60
//! frames shows, above its status lines, exactly the frame `rangewalk
//! synth` makes for the same camera and time; scripted keys move and turn
//! the viewer, and a move past the view space's edge ends on the edge.
//! Each test starts its own Xvfb on a display it picks and stops it; a
//! missing or failing Xvfb fails the test with the reason.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use glam::Vec3;
use rangewalk::synth::walk::frame_times;
use rangewalk::viewer::overlay;

mod common;

/// An X server of the test's own, stopped when dropped.
struct Xvfb {
    child: Child,
    display: String,
}

impl Xvfb {
    fn start() -> Xvfb {
        // `-displayfd 1`: Xvfb takes a free display and prints its number
        // once it accepts connections.
        let mut child = Command::new("Xvfb")
            .args([
                "-displayfd",
                "1",
                "-screen",
                "0",
                "640x480x24",
                "-nolisten",
                "tcp",
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| {
                panic!("cannot start Xvfb ({e}): install Debian's xvfb (`make deps` does)")
            });
        let stdout = child.stdout.take().expect("piped");
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut line = String::new();
            let _ = BufReader::new(stdout).read_line(&mut line);
            let _ = tx.send(line);
        });
        let line = rx
            .recv_timeout(Duration::from_secs(20))
            .unwrap_or_else(|_| {
                let _ = child.kill();
                panic!("Xvfb printed no display number within 20 s")
            });
        let number = line.trim();
        if number.parse::<u32>().is_err() {
            let status = child.try_wait();
            let _ = child.kill();
            panic!("Xvfb did not start: it printed `{number}` (exit: {status:?})");
        }
        Xvfb {
            child,
            display: format!(":{number}"),
        }
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn rangewalk(args: &[&str], display: Option<&str>) -> Output {
    let mut c = common::command();
    c.args(args);
    match display {
        Some(d) => c.env("DISPLAY", d),
        None => c.env_remove("DISPLAY"),
    };
    c.output().expect("running rangewalk")
}

fn ok(o: &Output, what: &str) -> String {
    let (out, err) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert!(o.status.success(), "{what} failed:\n{out}\n{err}");
    out.into_owned()
}

/// A small bake of the Cornell box (two views, two times, 256² sphere
/// bases, traced indirect light), made once for the tests of this file.
fn bake() -> &'static Path {
    static BAKE: OnceLock<PathBuf> = OnceLock::new();
    BAKE.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("viewer-bake");
        if dir.exists() {
            std::fs::remove_dir_all(&dir).unwrap();
        }
        let scene = common::scene_path("cornell-box");
        let o = rangewalk(
            &[
                "bake",
                scene.to_str().unwrap(),
                "--quality",
                "0.3",
                "--size",
                "256",
                "--spp",
                "2",
                "--indirect",
                "path",
                "--out",
                dir.to_str().unwrap(),
            ],
            None,
        );
        ok(&o, "baking the test's bake");
        dir
    })
}

/// Width, height and RGB bytes of a PNG.
fn read_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb, "{}", path.display());
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

const W: u32 = 160;
const H: u32 = 128;

/// Synth's options that make the viewer's drafts.
const DRAFT: [&str; 10] = [
    "--supersample",
    "1",
    "--filter",
    "cover",
    "--blend",
    "nearest",
    "--light-rays",
    "4",
    "--reshade-samples",
    "4",
];

#[test]
fn a_played_path_shows_what_synth_makes() {
    let x = Xvfb::start();
    let bake = bake().to_str().unwrap();
    // While the view moves the viewer shows drafts (by default), or the
    // frames of the options given.
    for (moving, synth_options) in [("draft", &DRAFT[..]), ("full", &[])] {
        let out = tempfile::tempdir().unwrap();
        let shot = out.path().join("shot.png");
        let size = format!("{W}x{H}");
        let start = Instant::now();
        let o = rangewalk(
            &[
                "view",
                bake,
                "--path",
                "walk",
                "--frames",
                "60",
                "--size",
                &size,
                "--moving",
                moving,
                "--screenshot",
                shot.to_str().unwrap(),
            ],
            Some(&x.display),
        );
        let text = ok(&o, &format!("rangewalk view --path walk --moving {moving}"));
        let drafts = if moving == "draft" { 60 } else { 0 };
        assert!(
            text.contains(&format!("60 frame(s) ({drafts} draft(s))")),
            "{text}"
        );
        eprintln!("{text}(in {:.1} s)", start.elapsed().as_secs_f64());

        // The path loops: frame 59 is its frame 59 mod 31 at 30 frames/s.
        let times = frame_times((0.0, 1.0), 30.0);
        let t = times[59 % times.len()];
        assert!(text.contains(&format!("t = {t} s")), "{text}");
        let t = t.to_string();
        let mut synth = vec!["--path", "walk", "--time", &t];
        synth.extend(synth_options);
        shows_what_synth_makes(&shot, &synth, out.path());
    }
}

/// Whether the screenshot `shot` shows, above its status lines, the frame
/// `rangewalk synth` makes with `synth_args` (its camera, time and
/// options) at the test's size; `out` for synth's files.
fn shows_what_synth_makes(shot: &Path, synth_args: &[&str], out: &Path) {
    let size = format!("{W}x{H}");
    let reference = out.join("synth.png");
    let exr = out.join("synth.exr");
    let mut args = vec!["synth", bake().to_str().unwrap()];
    args.extend(synth_args);
    args.extend([
        "--size",
        &size,
        "--out",
        exr.to_str().unwrap(),
        "--preview",
        reference.to_str().unwrap(),
    ]);
    ok(&rangewalk(&args, None), &format!("rangewalk {args:?}"));

    let (w, h, seen) = read_png(shot);
    let (rw, rh, made) = read_png(&reference);
    assert_eq!((w, h), (W, H), "the screenshot's size");
    assert_eq!((rw, rh), (W, H));
    let above = (H as usize - overlay::height(2)) * W as usize * 3;
    let differing = seen[..above]
        .iter()
        .zip(&made[..above])
        .filter(|(a, b)| a != b)
        .count();
    assert_eq!(
        differing, 0,
        "{differing} bytes above the status lines differ from rangewalk {args:?}"
    );
    assert!(
        made[..above].iter().any(|&v| v > 32),
        "the frame shows the box, not black"
    );
    assert_ne!(
        seen[above..],
        made[above..],
        "the status lines are drawn over the bottom rows"
    );
}

/// Runs an input script (and `more` arguments); the last frame's position,
/// direction and whether it was stopped at the edge, and what the run
/// printed.
fn scripted_with(x: &Xvfb, script: &str, more: &[&str]) -> (Vec3, Vec3, bool, String) {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("input.txt");
    std::fs::write(&file, script).unwrap();
    let size = format!("{W}x{H}");
    let mut args = vec![
        "view",
        bake().to_str().unwrap(),
        "--input",
        file.to_str().unwrap(),
        "--size",
        &size,
    ];
    args.extend(more);
    let o = rangewalk(&args, Some(&x.display));
    let text = ok(&o, &format!("rangewalk view --input `{script}`"));
    let line = text
        .lines()
        .find_map(|l| l.strip_prefix("last frame: position "))
        .unwrap_or_else(|| panic!("no last frame line in\n{text}"));
    let vec = |s: &str| -> Vec3 {
        let inner = s.trim().trim_start_matches('[');
        let inner = &inner[..inner.find(']').unwrap()];
        let v: Vec<f32> = inner
            .split(',')
            .map(|c| c.trim().parse().unwrap())
            .collect();
        Vec3::new(v[0], v[1], v[2])
    };
    let position = vec(line);
    let direction = vec(line.split("direction ").nth(1).unwrap());
    (
        position,
        direction,
        line.contains("stopped at the view space's edge"),
        text,
    )
}

fn scripted(x: &Xvfb, script: &str) -> (Vec3, Vec3, bool) {
    let (p, d, edge, _) = scripted_with(x, script, &[]);
    (p, d, edge)
}

#[test]
fn a_still_view_is_made_again_in_full() {
    let x = Xvfb::start();
    let out = tempfile::tempdir().unwrap();
    let shot = out.path().join("shot.png");
    // The first frame (nothing before it) is a draft; Space pauses time
    // before it, and the three frames after it show the same view at the
    // same time: in full.
    let (p, d, _, text) = scripted_with(
        &x,
        "1 space\n3\n",
        &["--screenshot", shot.to_str().unwrap()],
    );
    assert!(text.contains("4 frame(s) (1 draft(s))"), "{text}");
    assert!((p - Vec3::new(278.0, 273.0, -800.0)).length() < 1e-3, "{p}");
    assert!((d - Vec3::Z).length() < 1e-5, "{d}");
    let t = text
        .split("t = ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .unwrap_or_else(|| panic!("no time in\n{text}"));
    shows_what_synth_makes(&shot, &["--camera", "main", "--time", t], out.path());
}

#[test]
fn scripted_keys_move_and_turn_the_viewer_and_the_edge_holds() {
    let x = Xvfb::start();
    // The Cornell box's `main` camera stands at x = 278 on the view space,
    // the segment x in [78, 478] at y = 273, z = -800, looking along +z, so
    // the image's right is -x. The viewer moves a quarter of the segment,
    // 100 mm, per second: 30 frames at the scene's 30 frames/s.
    let (p, d, edge) = scripted(&x, "30 d\n");
    assert!(
        (p - Vec3::new(178.0, 273.0, -800.0)).length() < 0.01,
        "30 frames of `d` moved to {p}"
    );
    assert!((d - Vec3::Z).length() < 1e-5, "{d}");
    assert!(!edge);

    // 90 frames would go 300 mm; the segment ends 200 mm away.
    let (p, _, edge) = scripted(&x, "1\n90 d\n");
    assert_eq!(
        p,
        Vec3::new(78.0, 273.0, -800.0),
        "the move stops at the end"
    );
    assert!(edge, "the last step pushed against the edge");

    // Forward leaves the segment at once: the viewer stays where it is.
    let (p, _, edge) = scripted(&x, "10 w\n");
    assert!((p - Vec3::new(278.0, 273.0, -800.0)).length() < 1e-3, "{p}");
    assert!(edge);

    // One second of the left arrow turns 1.2 rad about the world's up.
    let (_, d, _) = scripted(&x, "30 left\n");
    let want = Vec3::new(1.2f32.sin(), 0.0, 1.2f32.cos());
    assert!((d - want).length() < 1e-3, "turned to {d}, not {want}");
}

#[test]
fn bad_input_is_refused_with_its_reason() {
    let bake = bake().to_str().unwrap();
    let err = |o: Output| {
        assert!(!o.status.success());
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let e = err(rangewalk(&["view", bake, "--path", "nowhere"], None));
    assert!(e.contains("`nowhere`") && e.contains("walk"), "{e}");
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("input.txt");
    std::fs::write(&file, "5 d\n2 jump\n").unwrap();
    let e = err(rangewalk(
        &["view", bake, "--input", file.to_str().unwrap()],
        None,
    ));
    assert!(
        e.contains("input.txt") && e.contains("line 2") && e.contains("`jump`"),
        "{e}"
    );
    let e = err(rangewalk(&["view", bake, "--frames", "3"], None));
    assert!(
        e.contains("DISPLAY is not set") && e.contains("Xvfb"),
        "{e}"
    );
}

#[test]
fn a_recording_replaces_only_a_recording() {
    let x = Xvfb::start();
    let root = tempfile::tempdir().unwrap();
    let frames = |dir: &Path| -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    let record = |dir: &Path, n: &str| {
        rangewalk(
            &[
                "view",
                bake().to_str().unwrap(),
                "--path",
                "walk",
                "--frames",
                n,
                "--size",
                "32x24",
                "--record",
                dir.to_str().unwrap(),
            ],
            Some(&x.display),
        )
    };
    let out = root.path().join("rec");
    ok(&record(&out, "3"), "recording 3 frames");
    assert_eq!(
        frames(&out),
        ["frame-0000.png", "frame-0001.png", "frame-0002.png"]
    );
    ok(&record(&out, "2"), "recording 2 frames over them");
    assert_eq!(frames(&out), ["frame-0000.png", "frame-0001.png"]);
    assert_eq!(frames(root.path()), ["rec"]);

    // A folder of the user's is refused before the window opens, and kept.
    let mine = root.path().join("mine");
    std::fs::create_dir(&mine).unwrap();
    std::fs::write(mine.join("frame-0000.png"), "").unwrap();
    std::fs::write(mine.join("holiday.jpg"), "").unwrap();
    let o = record(&mine, "2");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("refusing to replace") && err.contains("holiday.jpg"),
        "{err}"
    );
    assert_eq!(frames(&mine), ["frame-0000.png", "holiday.jpg"]);
}
