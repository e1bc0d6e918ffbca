use super::*;

const OBJ: &str = "o quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n\
                   o sliver\nv 0 0 0\nv 1 0 0\nv 2 0 0\nf 5 6 7\n";

fn scene_dir(toml: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("m.obj"), OBJ).unwrap();
    let path = dir.path().join("scene.toml");
    std::fs::write(&path, toml).unwrap();
    (dir, path)
}

const GOOD: &str = r#"
[animation]
start = 0
end = 1
fps = 30

[[materials]]
name = "white"
type = "diffuse"
reflectance = [0.5, 0.5, 0.5]

[[objects]]
name = "quad"
mesh = "m.obj"
group = "quad"
material = "white"
pivot = [0.5, 0.5, 0]
[[objects.keyframes]]
time = 0
[[objects.keyframes]]
time = 1
translate = [1, 0, 0]
rotate = { axis = [0, 0, 1], degrees = 90 }

[[cameras]]
name = "main"
position = [0.5, 0.5, -3]
look_at = [0.5, 0.5, 0]
vfov = 40
"#;

fn load_err(toml: &str) -> String {
    let (_d, path) = scene_dir(toml);
    format!("{:#}", Scene::load(path).unwrap_err())
}

#[test]
fn good_scene_loads() {
    let (_d, path) = scene_dir(GOOD);
    let s = Scene::load(path).unwrap();
    assert_eq!(s.objects.len(), 1);
    assert_eq!(s.objects[0].mesh.triangles.len(), 2);
    assert!(!s.is_static());
    // The pivot stays put while the quad turns; translation moves it.
    let c = s.at(1.0)[0].transform_point3(Vec3::new(0.5, 0.5, 0.0));
    assert!((c - Vec3::new(1.5, 0.5, 0.0)).length() < 1e-5, "{c}");
    assert_eq!(s.camera("main").unwrap().direction, Vec3::Z);
    assert!(s.camera("nope").unwrap_err().to_string().contains("main"));
}

#[test]
fn zero_area_triangles_are_dropped_and_counted() {
    let toml = GOOD.replace("group = \"quad\"\n", "");
    let (_d, path) = scene_dir(&toml);
    let s = Scene::load(path).unwrap();
    assert_eq!(s.dropped_triangles, 1);
    assert_eq!(s.objects[0].mesh.triangles.len(), 2);
}

#[test]
fn bad_inputs_name_what_is_wrong() {
    let cases: &[(&str, &str, &[&str])] = &[
        (
            "reflectance = [0.5, 0.5, 0.5]",
            "reflectance = [1.0, 0.5, 0.5]",
            &["white", ">= 1", "scene.toml:7"],
        ),
        (
            "reflectance = [0.5, 0.5, 0.5]",
            "reflectance = [nan, 0.5, 0.5]",
            &["reflectance", "not finite"],
        ),
        (
            "material = \"white\"",
            "material = \"gold\"",
            &["gold", "white", "quad"],
        ),
        (
            "translate = [1, 0, 0]",
            "translate = [inf, 0, 0]",
            &["translate", "not finite"],
        ),
        ("time = 1\n", "time = -1\n", &["increasing", "keyframe"]),
        (
            "mesh = \"m.obj\"",
            "mesh = \"missing.obj\"",
            &["missing.obj", "does not exist"],
        ),
        (
            "group = \"quad\"",
            "group = \"sliver\"",
            &["object `quad` has no triangles", "sliver", "zero area"],
        ),
        ("group = \"quad\"", "group = \"cube\"", &["cube", "quad"]),
        ("vfov = 40", "vfov = 400", &["vfov", "main"]),
        (
            "translate = [1, 0, 0]",
            "translate = [1e38, 0, 0]",
            &["object `quad` keyframe", "`translate`", "beyond"],
        ),
        (
            "translate = [1, 0, 0]",
            "translate = [1, 0, 0]\nscale = 1e38",
            &["object `quad` keyframe", "at time 1", "`scale`"],
        ),
        (
            "pivot = [0.5, 0.5, 0]",
            "pivot = [0.5, -1e38, 0]",
            &["object `quad`", "`pivot`", "beyond"],
        ),
        (
            "position = [0.5, 0.5, -3]",
            "position = [0.5, 0.5, -3e38]",
            &["camera `main`", "`position`", "beyond"],
        ),
        (
            "look_at = [0.5, 0.5, 0]",
            "look_at = [3e38, 0.5, 0]",
            &["camera `main`", "`look_at`", "beyond"],
        ),
        ("fps = 30", "fps = 30\nspeed = 2", &["speed"]),
        ("type = \"diffuse\"", "type = \"velvet\"", &["velvet"]),
        (
            "look_at = [0.5, 0.5, 0]",
            "look_at = [0.5, 0.5, -3]",
            &["direction"],
        ),
    ];
    for (from, to, needles) in cases {
        assert!(GOOD.contains(from), "{from}");
        let msg = load_err(&GOOD.replacen(from, to, 1));
        assert!(
            msg.contains("scene.toml") || msg.contains(".obj"),
            "no file named in: {msg}"
        );
        for n in *needles {
            assert!(msg.contains(n), "`{n}` missing from: {msg}");
        }
    }
}

/// A walk path through an animated scene stays within its animation
/// (beyond it nothing would move); a static scene's paths keep any
/// times.
#[test]
fn path_keys_of_an_animated_scene_lie_within_the_animation() {
    let path = "\n[[paths]]\nname = \"walk\"\n[[paths.keys]]\ntime = 0\nposition = [0, 0, -3]\ndirection = [0, 0, 1]\nvfov = 40\n[[paths.keys]]\ntime = 5\nposition = [1, 0, -3]\ndirection = [0, 0, 1]\nvfov = 40\n";
    let msg = load_err(&format!("{GOOD}{path}"));
    assert!(
        msg.contains("path `walk` key")
            && msg.contains("time 5 lies outside the animation [0, 1] s"),
        "{msg}"
    );
    let still = GOOD.replace(
        "translate = [1, 0, 0]\nrotate = { axis = [0, 0, 1], degrees = 90 }\n",
        "",
    );
    assert_ne!(still, GOOD);
    let (_d, p) = scene_dir(&format!("{still}{path}"));
    let s = Scene::load(p).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(s.is_static());
    assert!(s.check_time(-1.0).is_ok() && s.check_time(f32::NAN).is_err());
}

#[test]
fn names_must_be_unique() {
    let twice = format!("{GOOD}\n[[cameras]]\nname = \"main\"\nposition = [0, 0, -1]\ndirection = [0, 0, 1]\nvfov = 30\n");
    let msg = load_err(&twice);
    assert!(msg.contains("camera `main` is defined twice"), "{msg}");
}

#[test]
fn malformed_files_are_errors() {
    assert!(load_err("[[objects]\n").contains("scene.toml"));
    assert!(load_err("").contains("empty"));
    let dir = tempfile::tempdir().unwrap();
    let err = format!(
        "{:#}",
        Scene::load(dir.path().join("none.toml")).unwrap_err()
    );
    assert!(err.contains("none.toml"), "{err}");
}

/// A white texel (an 8-bit 255) under a reflectance below 1 loads; a
/// product of 1 is refused, naming the texture.
#[test]
fn texture_is_checked_as_a_product_with_the_reflectance() {
    let png = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/wavefront/checker.png");
    let textured = GOOD.replace(
        "reflectance = [0.5, 0.5, 0.5]",
        "reflectance = [0.8, 0.8, 0.8]\ntexture = \"t.png\"",
    );
    let (d, path) = scene_dir(&textured);
    std::fs::copy(png, d.path().join("t.png")).unwrap();
    let s = Scene::load(&path).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(matches!(
        &s.materials[0].bsdf,
        Bsdf::Diffuse {
            texture: Some(_),
            ..
        }
    ));
    // A high-dynamic-range texel of 2 under 0.8 is a reflectance of 1.6.
    exr::prelude::write_rgb_file(d.path().join("t.exr"), 2, 1, |_, _| {
        (2.0f32, 0.1f32, 0.1f32)
    })
    .unwrap();
    std::fs::write(&path, textured.replace("t.png", "t.exr")).unwrap();
    let msg = format!("{:#}", Scene::load(&path).unwrap_err());
    assert!(
        msg.contains("t.exr") && msg.contains("largest texel"),
        "{msg}"
    );
}

#[test]
fn nan_in_obj_is_an_error() {
    let (d, path) = scene_dir(GOOD);
    std::fs::write(
        d.path().join("m.obj"),
        "o quad\nv 0 0 0\nv nan 0 0\nv 1 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let msg = format!("{:#}", Scene::load(path).unwrap_err());
    assert!(msg.contains("m.obj") && msg.contains("finite"), "{msg}");
}
