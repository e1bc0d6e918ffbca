//! Our path tracer against Mitsuba 3 (`scalar_rgb`, `path` integrator) on the
//! same exported scenes. The method and the measured noise floors are in
//! `docs/validation.md`.
//!
//! Each comparison renders the scene twice with Mitsuba (two seeds) and once
//! with ours, and asks for
//! (a) the mean luminance (emitters seen directly masked out) within 0.5 % of
//!     Mitsuba's (the mean of both renders), and
//! (b) the relative RMS difference of 8x8 block means between ours and one
//!     Mitsuba render within twice that between the two Mitsuba renders.
//!
//! Mitsuba is run by `tests/mitsuba/render.py` with the interpreter named by
//! `RANGEWALK_PYTHON`, else `<repo>/.venv/bin/python` (made by `make test`).

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::Vec3;
use rangewalk::accel::{self, Backend};
use rangewalk::camera::Camera;
use rangewalk::export::mitsuba;
use rangewalk::image::NO_HIT;
use rangewalk::render::{render, RenderSettings};
use std::sync::Arc;

use glam::Vec2;
use rangewalk::camera::Projection;
use rangewalk::image::Texture;
use rangewalk::scene::{
    Animation, Bsdf, GlossyModel, Light, Material, Mesh, Motion, Object, Scene,
};

mod common;
use common::load;

const BLOCK: usize = 8;
const MAX_BIAS: f64 = 0.005;
const MAX_FLOOR_RATIO: f64 = 2.0;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The Python interpreter with Mitsuba 3, or a failure saying how to get one.
fn python() -> PathBuf {
    let candidates: Vec<PathBuf> = match std::env::var_os("RANGEWALK_PYTHON") {
        Some(p) => vec![PathBuf::from(p)],
        None => vec![repo().join(".venv/bin/python")],
    };
    for py in &candidates {
        let ok = Command::new(py)
            .args(["-c", "import mitsuba; mitsuba.set_variant('scalar_rgb')"])
            .output()
            .is_ok_and(|o| o.status.success());
        if ok {
            return py.clone();
        }
    }
    panic!(
        "no Python with Mitsuba 3 (scalar_rgb) found (tried {candidates:?}); run `make test`, \
         which creates .venv with mitsuba, or set RANGEWALK_PYTHON to an interpreter that has it"
    );
}

fn mitsuba_render(py: &Path, xml: &Path, seed: u32, out: &Path) -> Vec<Vec3> {
    let status = Command::new(py)
        .arg(repo().join("tests/mitsuba/render.py"))
        .arg(xml)
        .arg(seed.to_string())
        .arg(out)
        .status()
        .expect("running tests/mitsuba/render.py");
    assert!(status.success(), "Mitsuba failed on {}", xml.display());
    read_exr(out)
}

fn read_exr(path: &Path) -> Vec<Vec3> {
    use exr::prelude::*;
    let image = read_first_rgba_layer_from_file(
        path,
        |res, _| {
            (
                res.width(),
                vec![glam::Vec3::ZERO; res.width() * res.height()],
            )
        },
        |(w, px): &mut (usize, Vec<glam::Vec3>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = glam::Vec3::new(r, g, b);
        },
    )
    .unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
    image.layer_data.channel_data.pixels.1
}

fn write_exr(path: &Path, w: usize, h: usize, px: &[Vec3]) {
    exr::prelude::write_rgb_file(path, w, h, |x, y| {
        let c = px[y * w + x];
        (c.x, c.y, c.z)
    })
    .unwrap();
}

fn luminance(c: Vec3) -> f64 {
    (0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z) as f64
}

/// Pixels near a directly seen emitter (its centre ray or a neighbour's hits
/// one), whose partial coverage is all variance and no information.
fn emitter_mask(scene: &Scene, ids: &[u32], w: usize, h: usize) -> Vec<bool> {
    let emits = |id: u32| id != NO_HIT && scene.material_of(id).emission.is_some();
    let mut mask = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            if emits(ids[y * w + x]) {
                for yy in y.saturating_sub(1)..(y + 2).min(h) {
                    for xx in x.saturating_sub(1)..(x + 2).min(w) {
                        mask[yy * w + xx] = true;
                    }
                }
            }
        }
    }
    mask
}

struct Verdict {
    bias: f64,
    rms: f64,
}

/// Mean luminance of the unmasked pixels, and 8x8 block means of blocks with
/// no masked pixel.
fn stats(px: &[Vec3], mask: &[bool], w: usize, h: usize) -> (f64, Vec<f64>) {
    let (mut sum, mut n) = (0.0, 0usize);
    for (c, m) in px.iter().zip(mask) {
        if !m {
            sum += luminance(*c);
            n += 1;
        }
    }
    let mut blocks = Vec::new();
    for by in 0..h / BLOCK {
        for bx in 0..w / BLOCK {
            let idx =
                (0..BLOCK * BLOCK).map(|k| (by * BLOCK + k / BLOCK) * w + bx * BLOCK + k % BLOCK);
            if idx.clone().any(|i| mask[i]) {
                blocks.push(f64::NAN);
            } else {
                blocks.push(idx.map(|i| luminance(px[i])).sum::<f64>() / (BLOCK * BLOCK) as f64);
            }
        }
    }
    (sum / n as f64, blocks)
}

/// Relative RMS difference of block means, relative to the mean.
fn block_rms(a: &[f64], b: &[f64], mean: f64) -> f64 {
    let d: Vec<f64> = a
        .iter()
        .zip(b)
        .filter(|(x, _)| !x.is_nan())
        .map(|(x, y)| (x - y) * (x - y))
        .collect();
    (d.iter().sum::<f64>() / d.len() as f64).sqrt() / mean
}

struct Case<'a> {
    name: &'a str,
    scene: Scene,
    camera: Camera,
    time: f32,
    spp: u32,
    max_depth: Option<u32>,
}

/// Runs one comparison; returns the verdict of ours and (b)'s noise floor.
fn compare(case: &Case, wrong_albedo: bool) -> (Verdict, Verdict, f64) {
    let py = python();
    let dir = tempfile::Builder::new()
        .prefix(&format!("rangewalk-mitsuba-{}-", case.name))
        .tempdir()
        .unwrap();
    mitsuba::export(
        &case.scene,
        case.time,
        &case.camera,
        case.spp,
        case.max_depth,
        dir.path(),
    )
    .unwrap();
    let xml = dir.path().join("scene.xml");
    let a = mitsuba_render(&py, &xml, 1, &dir.path().join("mitsuba-1.exr"));
    let b = mitsuba_render(&py, &xml, 2, &dir.path().join("mitsuba-2.exr"));

    let time = case.time;
    let settings = RenderSettings {
        spp: case.spp,
        max_depth: case.max_depth,
        seed: 3,
    };
    let ours = |scene: &Scene| {
        let engine = accel::build(Backend::Bvh, &scene.geometry(), &scene.at(time)).unwrap();
        let (img, st) = render(scene, engine.as_ref(), &case.camera, time, &settings).unwrap();
        eprintln!(
            "{}: ours {:.2} s, {:.2} M rays/s",
            case.name,
            st.seconds,
            st.rays as f64 / st.seconds / 1e6
        );
        img
    };
    let img = ours(&case.scene);
    let (w, h) = (img.width as usize, img.height as usize);
    assert_eq!(a.len(), w * h, "Mitsuba image size differs from ours");
    write_exr(&dir.path().join("ours.exr"), w, h, &img.radiance);
    let mask = emitter_mask(&case.scene, &img.object_id, w, h);

    let (ma, ba) = stats(&a, &mask, w, h);
    let (mb, bb) = stats(&b, &mask, w, h);
    let reference = 0.5 * (ma + mb);
    let floor = block_rms(&ba, &bb, reference);
    let judge = |px: &[Vec3]| {
        let (m, blocks) = stats(px, &mask, w, h);
        Verdict {
            bias: m / reference - 1.0,
            rms: block_rms(&blocks, &ba, reference),
        }
    };
    let good = judge(&img.radiance);
    let bad = if wrong_albedo {
        let mut darker = case.scene.clone();
        for m in &mut darker.materials {
            if let Bsdf::Diffuse { reflectance, .. } = &mut m.bsdf {
                *reflectance *= 0.98;
            }
        }
        judge(&ours(&darker).radiance)
    } else {
        Verdict {
            bias: f64::NAN,
            rms: f64::NAN,
        }
    };
    eprintln!(
        "{}: Mitsuba seeds differ by {:+.4} %; ours: bias {:+.3} %, block RMS {:.4} vs floor {:.4} (ratio {:.2})",
        case.name,
        100.0 * (ma / mb - 1.0),
        100.0 * good.bias,
        good.rms,
        floor,
        good.rms / floor
    );
    let passed = good.bias.abs() < MAX_BIAS && good.rms < MAX_FLOOR_RATIO * floor;
    if !passed {
        let kept = dir.keep();
        eprintln!("{}: images kept in {}", case.name, kept.display());
    }
    (good, bad, floor)
}

fn check(case: Case) {
    let (good, _, floor) = compare(&case, false);
    assert_verdict(case.name, &good, floor);
}

fn assert_verdict(name: &str, v: &Verdict, floor: f64) {
    assert!(
        v.bias.abs() < MAX_BIAS,
        "{name}: mean luminance differs from Mitsuba's by {:+.3} % (limit {} %)",
        100.0 * v.bias,
        100.0 * MAX_BIAS
    );
    assert!(
        v.rms < MAX_FLOOR_RATIO * floor,
        "{name}: block RMS {:.4} exceeds {MAX_FLOOR_RATIO} x the noise floor {floor:.4}",
        v.rms
    );
}

const SIZE: u32 = 128;
const SPP: u32 = 256;

fn cornell(time: f32) -> Case<'static> {
    let scene = load("cornell-box");
    let camera = scene
        .camera("main")
        .unwrap()
        .perspective(SIZE, SIZE)
        .unwrap();
    Case {
        name: if time == 0.0 {
            "cornell-t0"
        } else {
            "cornell-t0.7"
        },
        scene,
        camera,
        time,
        spp: SPP,
        max_depth: None,
    }
}

/// The Cornell box at t = 0; also shows that a 2 % darker albedo fails.
#[test]
fn cornell_box_at_t0_matches_mitsuba() {
    let case = cornell(0.0);
    let (good, bad, floor) = compare(&case, true);
    assert_verdict(case.name, &good, floor);
    eprintln!(
        "{}: with 2 % darker diffuse albedo: bias {:+.3} %, block RMS ratio {:.2}",
        case.name,
        100.0 * bad.bias,
        bad.rms / floor
    );
    assert!(
        bad.bias.abs() > 2.0 * MAX_BIAS,
        "a 2 % darker albedo was not detected: bias {:+.3} %",
        100.0 * bad.bias
    );
}

#[test]
fn cornell_box_at_t07_matches_mitsuba() {
    check(cornell(0.7));
}

/// The glossy-sun scene, with two changes that keep the comparison exact and
/// its noise low: the Ward sphere becomes GGX (Mitsuba has no Ward lobe; Ward
/// is checked by the furnace tests instead), and the sun is widened to 5°
/// (its mirror caustic on the ground is found only by BSDF sampling in both
/// renderers; with the real 0.53° disk it would need 100 x the samples).
#[test]
fn glossy_sun_matches_mitsuba() {
    let mut scene = load("glossy-sun");
    for m in &mut scene.materials {
        if let Bsdf::Glossy { model, .. } = &mut m.bsdf {
            *model = GlossyModel::Ggx;
        }
    }
    for l in &mut scene.lights {
        if let Light::Sun {
            angular_diameter_deg,
            ..
        } = l
        {
            *angular_diameter_deg = 5.0;
        }
    }
    let camera = scene
        .camera("main")
        .unwrap()
        .perspective(SIZE, SIZE)
        .unwrap();
    check(Case {
        name: "glossy-sun",
        scene,
        camera,
        time: 1.0,
        spp: SPP,
        max_depth: None,
    });
}

/// A textured quad under a point light: a texture exported upside down or
/// mirrored would move its four coloured quadrants and fail (b).
#[test]
fn texture_orientation_matches_mitsuba() {
    let texture = Texture {
        source: "quadrants".into(),
        width: 2,
        height: 2,
        texels: vec![
            Vec3::new(0.9, 0.1, 0.1),
            Vec3::new(0.1, 0.9, 0.1),
            Vec3::new(0.1, 0.1, 0.9),
            Vec3::new(0.9, 0.9, 0.9),
        ],
    };
    let quad = Mesh {
        positions: vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        // Offset so that the texel borders fall inside the quad, not on it.
        uvs: Some(vec![
            Vec2::new(0.25, 0.25),
            Vec2::new(1.25, 0.25),
            Vec2::new(1.25, 1.25),
            Vec2::new(0.25, 1.25),
        ]),
    };
    let scene = Scene {
        source: "textured-quad".into(),
        objects: vec![Object {
            name: "quad".into(),
            mesh: quad,
            material: 0,
            motion: Motion::default(),
        }],
        materials: vec![Material {
            name: "quadrants".into(),
            bsdf: Bsdf::Diffuse {
                reflectance: Vec3::splat(0.8),
                texture: Some(Arc::new(texture)),
            },
            emission: None,
        }],
        lights: vec![Light::Point {
            position: Vec3::new(0.3, 0.5, -2.0),
            intensity: Vec3::splat(4.0),
        }],
        animation: Animation {
            start: 0.0,
            end: 0.0,
            fps: 1.0,
        },
        cameras: Vec::new(),
        view_space: None,
        paths: Vec::new(),
        dropped_triangles: 0,
        warnings: Vec::new(),
    };
    let camera = Camera::look_at(
        Vec3::new(0.0, 0.0, -3.0),
        Vec3::ZERO,
        Vec3::Y,
        Projection::Perspective { vfov_deg: 30.0 },
        64,
        64,
    )
    .unwrap();
    check(Case {
        name: "textured-quad",
        scene,
        camera,
        time: 0.0,
        spp: 64,
        max_depth: None,
    });
}
