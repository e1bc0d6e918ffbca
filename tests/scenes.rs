//! The bundled scenes load, and the Cornell box is the one the shared data
//! describes, moving as described.

use std::path::PathBuf;

use glam::{Vec2, Vec3};
use rangewalk::scene::{Bsdf, Scene};

mod common;
use common::{load, scenes_dir};

#[test]
fn every_bundled_scene_loads() {
    let mut n = 0;
    for entry in std::fs::read_dir(scenes_dir()).unwrap() {
        let path = entry.unwrap().path().join("scene.toml");
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e:#}"));
        assert!(!scene.objects.is_empty());
        assert!(
            scene.camera("main").is_ok(),
            "{} has no camera `main`",
            path.display()
        );
        assert_eq!(scene.dropped_triangles, 0, "{}", path.display());
        assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
        n += 1;
    }
    assert!(n >= 5, "expected the five bundled scenes, found {n}");
}

#[test]
fn cornell_box_matches_the_measured_data() {
    let s = load("cornell-box");
    let names: Vec<&str> = s.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "floor",
            "ceiling",
            "back",
            "green-wall",
            "red-wall",
            "light",
            "short-box",
            "tall-box"
        ]
    );
    let light = s.objects.iter().position(|o| o.name == "light").unwrap();
    let m = s.material_of(light as u32);
    let e = m.emission.expect("the light emits");
    assert_eq!(e.radiance, Vec3::new(17.0, 12.0, 4.0));
    assert!(!e.two_sided);
    // The light's winding normal points down, so it emits into the box.
    let mesh = &s.objects[light].mesh;
    let [a, b, c] = mesh.triangles[0].map(|i| mesh.positions[i as usize]);
    assert!((b - a).cross(c - a).normalize().dot(-Vec3::Y) > 0.999);
    assert!((mesh.area() - 130.0 * 105.0).abs() < 1e-2);
    let red = s.material_of(s.objects.iter().position(|o| o.name == "red-wall").unwrap() as u32);
    assert!(
        matches!(red.bsdf, Bsdf::Diffuse { reflectance, .. } if reflectance == Vec3::new(0.63, 0.065, 0.05))
    );
    let cam = s.camera("main").unwrap();
    assert_eq!(cam.position, Vec3::new(278.0, 273.0, -800.0));
    assert!((cam.vfov_deg - 2.0 * (12.5f32 / 35.0).atan().to_degrees()).abs() < 1e-3);
    assert!(!s.is_static() && !s.has_specular());
    assert_eq!(
        (s.animation.start, s.animation.end, s.animation.fps),
        (0.0, 1.0, 30.0)
    );
}

/// Convex polygons (the boxes' floor footprints) overlap unless one of their
/// edge normals separates them.
fn overlap(a: &[Vec2], b: &[Vec2]) -> bool {
    let axes = a
        .iter()
        .zip(a.iter().cycle().skip(1))
        .chain(b.iter().zip(b.iter().cycle().skip(1)));
    for (p, q) in axes {
        let n = (*q - *p).perp();
        let span = |poly: &[Vec2]| {
            poly.iter()
                .map(|v| v.dot(n))
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), d| {
                    (lo.min(d), hi.max(d))
                })
        };
        let (a0, a1) = span(a);
        let (b0, b1) = span(b);
        if a1 < b0 || b1 < a0 {
            return false;
        }
    }
    true
}

#[test]
fn cornell_boxes_move_as_described_and_stay_apart() {
    let s = load("cornell-box");
    let short = s
        .objects
        .iter()
        .position(|o| o.name == "short-box")
        .unwrap();
    let tall = s.objects.iter().position(|o| o.name == "tall-box").unwrap();
    for k in 0..=30 {
        let t = k as f32 / 30.0;
        let poses = s.at(t);
        let footprint = |i: usize| -> Vec<Vec2> {
            // The top face's four corners, in winding order.
            s.objects[i].mesh.positions[..4]
                .iter()
                .map(|&p| {
                    let w = poses[i].transform_point3(p);
                    Vec2::new(w.x, w.z)
                })
                .collect()
        };
        assert!(
            !overlap(&footprint(short), &footprint(tall)),
            "boxes overlap at t = {t}"
        );
        let moved = poses[short].transform_point3(Vec3::new(130.0, 165.0, 65.0));
        assert!((moved - Vec3::new(130.0 + 100.0 * t, 165.0, 65.0 - 50.0 * t)).length() < 1e-3);
        let corner = poses[tall].transform_point3(Vec3::new(423.0, 330.0, 247.0))
            - Vec3::new(368.5, 330.0, 351.25);
        let rest = Vec3::new(423.0 - 368.5, 0.0, 247.0 - 351.25);
        let angle = rest.angle_between(corner).to_degrees();
        assert!((angle - 30.0 * t).abs() < 1e-2, "t = {t}: turned {angle}°");
    }
}

#[test]
fn scaled_cornell_boxes_are_scaled_copies() {
    let base = load("cornell-box");
    for (name, scale) in [("cornell-box-1e-4", 1e-4f32), ("cornell-box-1e4", 1e4)] {
        let s = load(name);
        assert_eq!(s.objects.len(), base.objects.len());
        for t in [0.0, 0.5, 1.0] {
            let (pb, ps) = (base.at(t), s.at(t));
            for (i, (ob, os)) in base.objects.iter().zip(&s.objects).enumerate() {
                for (&a, &b) in ob.mesh.positions.iter().zip(&os.mesh.positions) {
                    let wa = pb[i].transform_point3(a) * scale;
                    let wb = ps[i].transform_point3(b);
                    assert!(
                        (wa - wb).length() <= 1e-4 * wa.length().max(scale),
                        "{name} {}: {wa} vs {wb}",
                        ob.name
                    );
                }
            }
        }
        let (cb, cs) = (base.camera("main").unwrap(), s.camera("main").unwrap());
        assert!((cb.position * scale - cs.position).length() <= 1e-5 * cs.position.length());
        assert!((cb.direction - cs.direction).length() < 1e-6);
    }
}

/// Meshes as other tools write them (`tests/wavefront/`): each pattern
/// loads with the fallback it needs and one warning naming its file, and
/// what is really broken is an error naming the file and line.
mod from_other_tools {
    use super::*;
    use rangewalk::scene::Material;

    fn dir() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/wavefront")
    }

    fn diffuse(s: &Scene, object: &str) -> (Vec3, bool) {
        let o = s.objects.iter().find(|o| o.name == object).unwrap();
        let m: &Material = &s.materials[o.material];
        match &m.bsdf {
            Bsdf::Diffuse {
                reflectance,
                texture,
            } => (*reflectance, texture.is_some()),
            other => panic!("{object}: {other:?}"),
        }
    }

    fn warnings_with<'a>(s: &'a Scene, needle: &str) -> Vec<&'a String> {
        s.warnings.iter().filter(|w| w.contains(needle)).collect()
    }

    #[test]
    fn patterns_of_other_tools_load_with_fallbacks() {
        let s = Scene::load(dir().join("others.toml")).unwrap_or_else(|e| panic!("{e:#}"));
        // No materials at all, and a missing MTL file: the default grey.
        assert_eq!(diffuse(&s, "plain"), (Vec3::splat(0.5), false));
        assert_eq!(diffuse(&s, "unshipped"), (Vec3::splat(0.5), false));
        assert_eq!(warnings_with(&s, "gone.mtl").len(), 1, "{:#?}", s.warnings);
        assert_eq!(warnings_with(&s, "no MTL material").len(), 2);
        // Kd 1 1 1: lowered just below 1, with one warning.
        assert_eq!(diffuse(&s, "white"), (Vec3::splat(0.99), false));
        assert_eq!(warnings_with(&s, "`white`").len(), 1);
        // map_Kd without Kd, behind options: the texture alone, whose
        // white texel brings the product to 1, so it is lowered too.
        assert_eq!(diffuse(&s, "wood"), (Vec3::splat(0.99), true));
        assert_eq!(warnings_with(&s, "`wood`").len(), 1);
        // A white texel under Kd below 1 is fine; the placement option
        // `-s` is ignored with a warning naming the line.
        assert_eq!(diffuse(&s, "tinted"), (Vec3::new(0.8, 0.7, 0.6), true));
        assert_eq!(warnings_with(&s, "textured.mtl:12").len(), 1);
        // A missing texture: Kd alone.
        assert_eq!(diffuse(&s, "lost"), (Vec3::splat(0.4), false));
        assert_eq!(warnings_with(&s, "missing.png").len(), 1);
        // Neither Kd nor map_Kd: the default grey, as for no material at
        // all, with one warning naming the MTL file and the material.
        assert_eq!(diffuse(&s, "bare"), (Vec3::splat(0.5), false));
        let bare = warnings_with(&s, "`bare`");
        assert_eq!(bare.len(), 1, "{:#?}", s.warnings);
        assert!(
            bare[0].contains("textured.mtl") && bare[0].contains("neither `Kd`"),
            "{}",
            bare[0]
        );
        // `Ke` emits (tobj reads it as `emissive`, where it was once not
        // looked for), and `Kd 0.2` is a grey.
        assert_eq!(diffuse(&s, "glow"), (Vec3::splat(0.2), false));
        let glow = s.objects.iter().find(|o| o.name == "glow").unwrap();
        let emission = s.materials[glow.material].emission.as_ref();
        assert_eq!(emission.map(|e| e.radiance), Some(Vec3::new(3.0, 2.0, 1.0)));
        assert_eq!(s.warnings.len(), 8, "{:#?}", s.warnings);
    }

    #[test]
    fn a_face_cut_short_is_an_error_naming_the_line() {
        let e = format!(
            "{:#}",
            Scene::load(dir().join("truncated.toml")).unwrap_err()
        );
        assert!(
            e.contains("truncated.obj:8") && e.contains("2 corner"),
            "{e}"
        );
    }
}
