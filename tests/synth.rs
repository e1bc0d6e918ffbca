//! Walk-through synthesis: a base reprojected into its own camera is the
//! base, a pinhole frame from a sphere base at the same point is the base
//! resampled, subpixels resolve silhouettes, frames between bases match
//! renders, motion compensation and
//! re-shading remove the errors they are for, and bad input is refused.

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::Vec3;
use rangewalk::accel::Backend;
use rangewalk::bake::{self, BaseProjection, IndirectSource, Settings, Shard};
use rangewalk::camera::{Camera, Projection};
use rangewalk::eval::metrics::{self, luminance};
use rangewalk::image::{RangeImage, NO_HIT};
use rangewalk::plan::{Plan, PlannedView};
use rangewalk::quality::Quality;
use rangewalk::radiosity::lookup::IrradianceCache;
use rangewalk::render::{self, RenderSettings};
use rangewalk::scene::Scene;
use rangewalk::synth::{Blend, Fill, Filter, Options, Synthesizer, TimeInterp, DEFAULT_BUDGET};

mod common;
use common::{engine_at as engine, load_path as load, rangewalk, scene_path};

/// Views at the Cornell box's view-space ends, each at `times`.
fn ends(scene: &Scene, times: &[f32]) -> Plan {
    let Some(rangewalk::scene::ViewSpace::Segment { a, b }) = scene.view_space else {
        panic!("the Cornell box's view space is a segment");
    };
    Plan {
        quality: Quality::new(0.6).unwrap(),
        views: [a, b]
            .map(|position| PlannedView {
                position,
                times: times.to_vec(),
            })
            .to_vec(),
        light_times: times.to_vec(),
        ..Plan::default()
    }
}

fn settings(size: u32, spp: u32) -> Settings {
    Settings {
        quality: rangewalk::quality::Quality::new(0.6).unwrap(),
        size,
        spp,
        projection: BaseProjection::Sphere,
        indirect: IndirectSource::Path,
        seed: 3,
        backend: Backend::default_available(),
        max_depth: None,
        planning: Default::default(),
    }
}

fn bake_into(scene: &Scene, dir: &Path, settings: &Settings, plan: Plan) -> bake::Bake {
    let mut e = engine(scene, 0.0);
    bake::run(scene, dir, settings, Shard::ALL, e.as_mut(), |_| Ok(plan))
        .unwrap_or_else(|e| panic!("{e:#}"));
    bake::Bake::open(dir, scene).unwrap_or_else(|e| panic!("{e:#}"))
}

/// Half floats keep 11 significant bits: a stored radiance is within this
/// relative distance of the baked one.
const HALF: f32 = 1.0 / 2048.0;

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b)
        .abs()
        .cmple(b.abs() * HALF + Vec3::splat(1e-6))
        .all()
}

fn path_traced(scene: &Scene, camera: &Camera, t: f32, spp: u32) -> RangeImage {
    path_traced_with_seed(scene, camera, t, spp, 11)
}

fn path_traced_with_seed(
    scene: &Scene,
    camera: &Camera,
    t: f32,
    spp: u32,
    seed: u64,
) -> RangeImage {
    let e = engine(scene, t);
    let s = RenderSettings {
        spp,
        max_depth: None,
        seed,
    };
    render::render(scene, e.as_ref(), camera, t, &s).unwrap().0
}

#[test]
fn a_base_reprojected_into_its_own_camera_is_the_base() {
    let scene = load(&scene_path("cornell-box"));
    let dir = tempfile::tempdir().unwrap();
    let baked = bake_into(
        &scene,
        dir.path(),
        &settings(64, 1),
        ends(&scene, &[0.0, 1.0]),
    );
    let base = baked.read(0).unwrap().image;
    let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
    // A splat in its own camera is its own pixel, whichever pixels it
    // reaches.
    for (fill, filter) in [
        (Fill::None, Filter::Box),
        (Fill::Both, Filter::Box),
        (Fill::Both, Filter::Cover),
    ] {
        // Reprojection alone (and the sky, with a background fill):
        // tracing the light replaces the base's own pixels there.
        let opts = Options {
            fill,
            filter,
            bases: 1,
            light_rays: 0,
            ..Options::default()
        };
        let (frame, stats) = synth
            .frame(&base.meta.camera, base.meta.time, &opts)
            .unwrap();
        assert_eq!(
            stats.images,
            [0],
            "one base image, the one at this view and time"
        );
        assert_eq!(
            stats.holes, 0,
            "{fill:?}: every pixel of the base lands on itself"
        );
        let mut surfaces = 0;
        for k in 0..base.len() {
            // With a background fill the frame's own rays find its sky (the
            // Cornell box has none: black), at each subpixel: where one
            // meets the wall beside it, that subpixel takes the wall's light
            // from a neighbour, as a render's samples would, and the wall
            // may hold most of the pixel.
            if fill == Fill::Both && base.object_id[k] == NO_HIT {
                let (w, x, y) = (base.meta.camera.width as usize, k % 64, k / 64);
                let neighbours: Vec<usize> = (0..9)
                    .filter_map(|i| {
                        let (u, v) = ((x + i % 3).checked_sub(1)?, (y + i / 3).checked_sub(1)?);
                        (u < w && v < base.len() / w).then_some(v * w + u)
                    })
                    .collect();
                assert!(
                    neighbours
                        .iter()
                        .any(|&n| base.object_id[n] == frame.object_id[k]),
                    "{fill:?}: pixel {k} shows object {}, which no base pixel beside it does",
                    frame.object_id[k]
                );
                let brightest = neighbours
                    .iter()
                    .fold(Vec3::ZERO, |m, &n| m.max(base.radiance[n]));
                assert!(
                    frame.radiance[k].cmpge(Vec3::ZERO).all()
                        && frame.radiance[k].cmple(brightest * (1.0 + HALF)).all(),
                    "{fill:?}: pixel {k}: {} beyond its neighbours' {brightest}",
                    frame.radiance[k],
                );
            } else {
                assert_eq!(frame.object_id[k], base.object_id[k], "{fill:?}: pixel {k}");
                let expected = base.radiance[k];
                assert!(
                    close(frame.radiance[k], expected),
                    "{fill:?}: pixel {k}: {} against {expected}",
                    frame.radiance[k],
                );
            }
            if base.object_id[k] != NO_HIT {
                surfaces += 1;
                let d = (frame.distance[k] - base.distance[k]).abs();
                assert!(d <= 1e-4 * base.distance[k], "pixel {k}: distance {d} off");
            }
        }
        assert!(surfaces > 100, "the base sees the box");
    }
}

#[test]
fn a_pinhole_frame_from_a_sphere_base_at_its_point_is_the_base_resampled() {
    let scene = load(&scene_path("cornell-box"));
    let dir = tempfile::tempdir().unwrap();
    // Base pixels finer than the frame's, as the bake's size rule makes them.
    let baked = bake_into(&scene, dir.path(), &settings(256, 1), ends(&scene, &[0.0]));
    let base = baked.read(0).unwrap().image;
    let sphere = base.meta.camera;
    let camera = Camera::looking(
        sphere.position,
        Vec3::new(0.3, -0.1, 1.0),
        Vec3::Y,
        Projection::Perspective { vfov_deg: 40.0 },
        48,
        40,
    )
    .unwrap();
    let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
    let opts = Options {
        bases: 1,
        light_rays: 0,
        ..Options::default()
    };
    let (frame, stats) = synth.frame(&camera, 0.0, &opts).unwrap();
    assert_eq!(stats.holes, 0);
    // Resampling: each frame pixel averages the base pixels whose
    // footprints (the parallelograms their neighbours span) overlap it, by
    // the area they cover. Frame pixels here are about 1.1 base pixels
    // across and the sphere's pixels are sheared, so a footprint reaching
    // into the pixel has its centre within two base pixels of the pixel's
    // ray: a frame pixel holds the base pixel under its ray, or a mean of
    // base pixels within two of it.
    let mut same = 0;
    for y in 0..camera.height {
        for x in 0..camera.width {
            let k = (y * camera.width + x) as usize;
            let ray = camera.ray(x as f32 + 0.5, y as f32 + 0.5).unwrap();
            let at = sphere.project(sphere.position + ray.dir).unwrap();
            let (bx, by) = (at.x as i64, at.y as i64);
            let pixel = |dx: i64, dy: i64| {
                let (i, j) = (
                    (bx + dx).clamp(0, 255) as u32,
                    (by + dy).clamp(0, 255) as u32,
                );
                base.radiance[(j * sphere.width + i) as usize]
            };
            if close(frame.radiance[k], pixel(0, 0)) {
                same += 1;
                continue;
            }
            let near: Vec<Vec3> = (-2..=2)
                .flat_map(|dy| (-2..=2).map(move |dx| (dx, dy)))
                .map(|(dx, dy)| pixel(dx, dy))
                .collect();
            let lo = near.iter().fold(Vec3::INFINITY, |m, c| m.min(*c));
            let hi = near.iter().fold(Vec3::NEG_INFINITY, |m, c| m.max(*c));
            let c = frame.radiance[k];
            assert!(
                c.cmpge(lo * (1.0 - HALF) - 1e-6).all() && c.cmple(hi * (1.0 + HALF) + 1e-6).all(),
                "pixel ({x}, {y}): {c} is no mean of the base pixels near its ray ({lo} to {hi})"
            );
        }
    }
    let n = (camera.width * camera.height) as usize;
    assert!(
        same > 0,
        "{same} of {n} pixels are the base pixel under their ray"
    );
}

#[test]
fn subpixels_show_each_surface_by_its_share_where_a_silhouette_crosses_a_pixel() {
    let scene = load(&scene_path("cornell-box"));
    let camera = main_camera(&scene);
    let dir = tempfile::tempdir().unwrap();
    // A sphere base at the camera, finer than the frame's pixels: what a
    // frame pixel shows is all in the base, so the error left on edges is
    // resampling's.
    let plan = Plan {
        quality: Quality::new(0.6).unwrap(),
        views: vec![PlannedView {
            position: camera.position,
            times: vec![0.0],
        }],
        light_times: vec![0.0],
        ..Plan::default()
    };
    let baked = bake_into(&scene, dir.path(), &settings(512, 8), plan);
    let reference = path_traced(&scene, &camera, 0.0, 256);
    let (w, h) = (camera.width as i64, camera.height as i64);
    let id =
        |x: i64, y: i64| reference.object_id[(y.clamp(0, h - 1) * w + x.clamp(0, w - 1)) as usize];
    // Pixels beside a silhouette (a neighbour shows another object), away
    // from the light, whose rim is traced rather than resampled.
    let mut e = engine(&scene, 0.0);
    let lit = rangewalk::eval::experiments::common::synthesize::emitter_free(
        &scene,
        e.as_mut(),
        &camera,
        0.0,
    )
    .unwrap()
    .expect("the light is in view");
    let edge: Vec<bool> = (0..w * h)
        .map(|k| {
            let (x, y) = (k % w, k / w);
            lit[k as usize] && !(-1..=1).all(|dy| (-1..=1).all(|dx| id(x + dx, y + dy) == id(x, y)))
        })
        .collect();
    assert!(
        edge.iter().filter(|e| **e).count() > 100,
        "the boxes' edges"
    );
    let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
    let mut errors = Vec::new();
    for supersample in [1, 2] {
        let opts = Options {
            bases: 1,
            supersample,
            ..Options::default()
        };
        let (frame, stats) = synth.frame(&camera, 0.0, &opts).unwrap();
        assert_eq!(stats.holes, 0, "{supersample}: fill both leaves no hole");
        let e = metrics::compare(&frame, &reference, Some(&edge)).unwrap();
        let all = metrics::compare(&frame, &reference, None).unwrap();
        eprintln!(
            "{supersample}x{supersample} subpixels: edge LRMS {:.4}, whole frame {:.4}",
            e.lrms, all.lrms
        );
        errors.push(e.lrms);
    }
    // Without subpixels the nearer surface takes every pixel it reaches
    // whole; with them each covers its share, as the render's pixels do.
    assert!(
        errors[1] < errors[0],
        "edge pixels: {:.4} with 2x2 subpixels against {:.4} without",
        errors[1],
        errors[0]
    );
}

/// The Cornell box from the `main` camera, midway between the bases.
fn main_camera(scene: &Scene) -> Camera {
    scene.camera("main").unwrap().perspective(64, 64).unwrap()
}

#[test]
fn a_frame_between_two_bases_matches_a_render_of_its_view() {
    let scene = load(&scene_path("cornell-box"));
    let dir = tempfile::tempdir().unwrap();
    let baked = bake_into(&scene, dir.path(), &settings(512, 16), ends(&scene, &[0.0]));
    let camera = main_camera(&scene);
    let reference = path_traced(&scene, &camera, 0.0, 1024);
    let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
    let (both, stats) = synth.frame(&camera, 0.0, &Options::default()).unwrap();
    assert_eq!(stats.images.len(), 2, "both views");
    assert_eq!(stats.holes, 0, "fill both leaves no hole");
    let all = metrics::compare(&both, &reference, None).unwrap();
    // Inside surfaces (pixels whose neighbours show the same object): the
    // shading carried over from the bases, within the noise of their 16
    // samples per pixel. Other edges are resampled from one or two base
    // pixels each; the whole frame's bias bounds them.
    let (w, h) = (camera.width as i64, camera.height as i64);
    let id =
        |x: i64, y: i64| reference.object_id[(y.clamp(0, h - 1) * w + x.clamp(0, w - 1)) as usize];
    let inside: Vec<bool> = (0..w * h)
        .map(|k| {
            let (x, y) = (k % w, k / w);
            (-1..=1).all(|dy| (-1..=1).all(|dx| id(x + dx, y + dy) == id(x, y)))
        })
        .collect();
    let e = metrics::compare(&both, &reference, Some(&inside)).unwrap();
    eprintln!(
        "LRMS {:.4} (all pixels {:.4}), bias {:+.4}",
        e.lrms, all.lrms, all.bias
    );
    // The light: each frame pixel takes one base pixel, and where the light
    // meets the ceiling that pixel is all light or all ceiling while the
    // render sees the fraction each covers; tracing the light's pixels
    // must take away the larger part of the whole frame's error.
    let untraced = Options {
        light_rays: 0,
        ..Options::default()
    };
    let (plain, plain_stats) = synth.frame(&camera, 0.0, &untraced).unwrap();
    let plain = metrics::compare(&plain, &reference, None).unwrap();
    eprintln!(
        "whole frame: LRMS {:.4} with {} pixels at the light traced, {:.4} without",
        all.lrms, stats.light_pixels, plain.lrms
    );
    assert_eq!(plain_stats.light_pixels, 0);
    assert!(e.lrms < 0.2, "LRMS {:.4} against a 1024-spp render", e.lrms);
    assert!(all.bias.abs() < 0.03, "bias {:+.4}", all.bias);
    assert!(stats.light_pixels > 0, "the light's rim is traced");
    // Splats that reach only the pixels whose centres they cover: the
    // same goals.
    let cover = Options {
        filter: Filter::Cover,
        ..Options::default()
    };
    let (covered, covered_stats) = synth.frame(&camera, 0.0, &cover).unwrap();
    assert_eq!(covered_stats.holes, 0, "cover: fill both leaves no hole");
    let c = metrics::compare(&covered, &reference, Some(&inside)).unwrap();
    let c_all = metrics::compare(&covered, &reference, None).unwrap();
    eprintln!(
        "cover: LRMS {:.4} (all pixels {:.4}), bias {:+.4}",
        c.lrms, c_all.lrms, c_all.bias
    );
    assert!(
        c.lrms < 0.2,
        "cover: LRMS {:.4} against a 1024-spp render",
        c.lrms
    );
    assert!(c_all.bias.abs() < 0.03, "cover: bias {:+.4}", c_all.bias);
    // Nearest first (the paper's order, pinterp's -q), which leaves out
    // what the second base cannot change: the same goals.
    let nearest = Options {
        blend: Blend::Nearest,
        ..Options::default()
    };
    let (first, first_stats) = synth.frame(&camera, 0.0, &nearest).unwrap();
    assert_eq!(first_stats.holes, 0, "nearest: fill both leaves no hole");
    assert!(
        first_stats.hidden > 0,
        "nearest: nothing hidden was left out"
    );
    let n = metrics::compare(&first, &reference, Some(&inside)).unwrap();
    let n_all = metrics::compare(&first, &reference, None).unwrap();
    eprintln!(
        "nearest: LRMS {:.4} (all pixels {:.4}), bias {:+.4}, {} base pixels left out",
        n.lrms, n_all.lrms, n_all.bias, first_stats.hidden
    );
    assert!(
        n.lrms < 0.2,
        "nearest: LRMS {:.4} against a 1024-spp render",
        n.lrms
    );
    assert!(n_all.bias.abs() < 0.03, "nearest: bias {:+.4}", n_all.bias);
    assert!(
        all.lrms < 0.5 * plain.lrms,
        "whole frame: LRMS {:.4} traced, {:.4} not",
        all.lrms,
        plain.lrms
    );
    // Frame pixels finer than the bases': without fill, pixels between
    // projected samples and what neither base saw stay holes; with both
    // fills none does.
    let fine = scene.camera("main").unwrap().perspective(192, 192).unwrap();
    let mut holes = |fill| {
        let opts = Options {
            fill,
            ..Options::default()
        };
        synth.frame(&fine, 0.0, &opts).unwrap().1.holes
    };
    let none = holes(Fill::None);
    assert!(none > 0, "without fill, holes stay");
    assert!(none < 192 * 192 / 2, "{none} holes");
    assert_eq!(holes(Fill::Both), 0);
}

/// Luminance error of `frame` against `reference` over `mask`.
fn error(frame: &RangeImage, reference: &RangeImage, mask: &[bool]) -> f64 {
    metrics::compare(frame, reference, Some(mask)).unwrap().lrms
}

#[test]
fn motion_compensation_and_reshading_remove_the_errors_they_are_for() {
    let scene = load(&scene_path("cornell-box"));
    let dir = tempfile::tempdir().unwrap();
    // Bases only at the animation's ends: half way, the boxes have moved
    // by 112 mm and 15 degrees.
    let baked = bake_into(
        &scene,
        dir.path(),
        &settings(512, 16),
        ends(&scene, &[0.0, 1.0]),
    );
    let camera = main_camera(&scene);
    let t = 0.5;
    let reference = path_traced(&scene, &camera, t, 1024);
    let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
    let mut frame = |time_interp| {
        let opts = Options {
            time_interp,
            ..Options::default()
        };
        synth.frame(&camera, t, &opts).unwrap().0
    };
    let linear = frame(TimeInterp::Linear);
    let motion = frame(TimeInterp::Motion);
    let reshade = frame(TimeInterp::Reshade);
    // Where the boxes are at t (or were at either end): ghosts of linear
    // blending live there.
    let ends: Vec<RangeImage> = [0.0, 1.0]
        .iter()
        .map(|&s| path_traced(&scene, &camera, s, 64))
        .collect();
    let moving = |o: u32| o == 6 || o == 7;
    let boxes: Vec<bool> = (0..reference.len())
        .map(|k| moving(reference.object_id[k]) || ends.iter().any(|e| moving(e.object_id[k])))
        .collect();
    let (l, m) = (
        error(&linear, &reference, &boxes),
        error(&motion, &reference, &boxes),
    );
    assert!(
        m < 0.8 * l,
        "on the moving boxes: motion {m:.4}, linear {l:.4}"
    );
    // Static surfaces whose direct light changes between the ends: the
    // boxes' shadows on the floor and walls.
    let lit = |e: &RangeImage, k: usize| luminance(e.radiance[k]);
    let shadows: Vec<bool> = (0..reference.len())
        .map(|k| {
            !boxes[k]
                && reference.object_id[k] != NO_HIT
                && (lit(&ends[0], k) - lit(&ends[1], k)).abs() > 0.5 * lit(&reference, k)
        })
        .collect();
    assert!(shadows.iter().filter(|&&s| s).count() > 20, "shadows move");
    let (m, r) = (
        error(&motion, &reference, &shadows),
        error(&reshade, &reference, &shadows),
    );
    assert!(
        r < 0.8 * m,
        "where shadows move: reshade {r:.4}, motion {m:.4}"
    );
    // A frame is seen through its bases' noise, but a moved shadow must
    // not add its own: with a few light samples a pixel it turns to salt
    // and pepper (each subpixel lit or not). Re-shaded, it is no worse
    // than a render taking the bases' own samples a pixel.
    let rendered = error(
        &path_traced_with_seed(&scene, &camera, t, 16, 99),
        &reference,
        &shadows,
    );
    eprintln!("where shadows move: reshade {r:.4}, a 16-spp render {rendered:.4}");
    assert!(
        r <= rendered,
        "where shadows move: reshade {r:.4}, a 16-spp render (the bases' samples) {rendered:.4}"
    );
    // At a base time nothing has moved since the bake: re-shading draws the
    // same light samples at the frame's time as at the base's and must
    // leave every pixel as the base holds it, adding no noise of its own.
    let mut at_base = |time_interp| {
        let opts = Options {
            time_interp,
            ..Options::default()
        };
        synth.frame(&camera, 0.0, &opts).unwrap().0
    };
    let (motion, reshade) = (at_base(TimeInterp::Motion), at_base(TimeInterp::Reshade));
    let changed = (0..motion.len())
        .filter(|&k| {
            let (a, b) = (motion.radiance[k], reshade.radiance[k]);
            (a - b).abs().max_element() > 1e-5 * a.abs().max_element().max(1e-3)
        })
        .count();
    assert_eq!(changed, 0, "pixels re-shading changed at a base time");
}

/// The Cornell box's back wall made a mirror, in which the camera sees the
/// ceiling light.
#[test]
fn a_light_seen_in_a_mirror_keeps_its_radiance_when_reshaded() {
    let mut scene = load(&scene_path("cornell-box"));
    let back = scene.objects.iter().position(|o| o.name == "back").unwrap();
    scene.materials.push(rangewalk::scene::Material {
        name: "mirror".into(),
        bsdf: rangewalk::scene::Bsdf::Mirror {
            reflectance: Vec3::splat(0.9),
        },
        emission: None,
    });
    scene.objects[back].material = scene.materials.len() - 1;
    let dir = tempfile::tempdir().unwrap();
    // Bases coarse enough that the light is a few pixels across, most of
    // them mixed with the ceiling.
    let baked = bake_into(&scene, dir.path(), &settings(128, 4), ends(&scene, &[0.0]));
    let camera = scene.camera("main").unwrap().perspective(128, 128).unwrap();
    let reference = path_traced(&scene, &camera, 0.0, 64);
    let opts = Options {
        time_interp: TimeInterp::Reshade,
        ..Options::default()
    };
    let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
    let frame = synth.frame(&camera, 0.0, &opts).unwrap().0;
    // The mirror's pixels the light's image covers at least half of.
    let light = scene.materials.iter().find_map(|m| m.emission).unwrap();
    let full = 0.9 * luminance(light.radiance);
    let image: Vec<usize> = (0..reference.len())
        .filter(|&k| {
            reference.object_id[k] == back as u32 && luminance(reference.radiance[k]) > 0.5 * full
        })
        .collect();
    assert!(
        image.len() >= 4,
        "the light in the mirror: {} pixels",
        image.len()
    );
    let mean = |img: &RangeImage| {
        image
            .iter()
            .map(|&k| luminance(img.radiance[k]))
            .sum::<f64>()
            / image.len() as f64
    };
    // A pixel shows the light's image whole or not at all, the reference
    // its share of it (at least half): the two means agree to within the
    // rim's share, never by the factor of three that lights mixed with
    // their surroundings in the bases gave.
    let (got, want) = (mean(&frame), mean(&reference));
    assert!(
        (0.75..=1.35).contains(&(got / want)),
        "the light in the mirror: {got:.3} synthesized, {want:.3} rendered"
    );
}

#[test]
fn bad_input_is_refused_and_leaves_nothing_half_written() {
    // The Cornell box with a camera behind its view space.
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("scene");
    std::fs::create_dir(&copy).unwrap();
    let source = scene_path("cornell-box");
    std::fs::copy(
        source.with_file_name("cornell-box.obj"),
        copy.join("cornell-box.obj"),
    )
    .unwrap();
    let text = std::fs::read_to_string(&source).unwrap()
        + "\n[[cameras]]\nname = \"behind\"\nposition = [278, 273, -1400]\nlook_at = [278, 273, 0]\nvfov = 30\n";
    std::fs::write(copy.join("scene.toml"), text).unwrap();
    let scene = load(&copy.join("scene.toml"));
    let bake_dir = dir.path().join("bake");
    bake_into(
        &scene,
        &bake_dir,
        &settings(32, 1),
        ends(&scene, &[0.0, 1.0]),
    );
    let bake_s = bake_dir.to_str().unwrap();
    let out = dir.path().join("frame.exr");
    let out_s = out.to_str().unwrap();

    // An unknown camera and an unknown path: errors naming what exists.
    let o = rangewalk(&[
        "synth", bake_s, "--camera", "nope", "--time", "0", "--out", out_s,
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("no camera named `nope`") && err.contains("main"),
        "{err}"
    );
    let walk_out = dir.path().join("walk");
    let walk_s = walk_out.to_str().unwrap();
    let o = rangewalk(&[
        "walk", bake_s, "--path", "nope", "--size", "16x16", "--out", walk_s,
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("no path named `nope`") && err.contains("walk"),
        "{err}"
    );
    assert!(!walk_out.exists() && !dir.path().join("walk.partial").exists());

    // An output that cannot be written: refused before the bake is read,
    // nothing written.
    for (bad, needle) in [
        (
            "/nonexistent/dir/x.exr",
            "folder /nonexistent/dir does not exist",
        ),
        (&*dir.path().join("frame.txt").to_string_lossy(), "`.txt`"),
    ] {
        let o = rangewalk(&["synth", bake_s, "--time", "0", "--out", bad]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(needle), "{err}");
        assert!(!Path::new(bad).exists());
    }

    // A camera outside the view space is a warning, and the frame is made.
    let o = rangewalk(&[
        "synth", bake_s, "--camera", "behind", "--time", "0.5", "--size", "16x16", "--out", out_s,
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("outside the scene's view space"), "{err}");
    assert!(out.exists());
    std::fs::remove_file(&out).unwrap();

    // A damaged base image (the planes file synthesis reads): an error
    // naming it, no frame written.
    let m = bake::Manifest::read(&bake_dir).unwrap();
    let victim = bake::manifest::planes_path(&bake_dir.join(&m.images[0].file));
    let mut bytes = std::fs::read(&victim).unwrap();
    let n = bytes.len();
    bytes.truncate(n / 2);
    std::fs::write(&victim, bytes).unwrap();
    let o = rangewalk(&[
        "synth", bake_s, "--time", "0", "--size", "16x16", "--out", out_s,
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains(&m.images[0].file),
        "{err}"
    );
    assert!(!out.exists(), "no frame from a damaged bake");

    // A bake of another scene.
    let other = scene_path("cornell-box-1e4");
    let o = rangewalk(&[
        "synth",
        bake_s,
        "--scene",
        other.to_str().unwrap(),
        "--time",
        "0",
        "--out",
        out_s,
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("differs"), "{err}");
}

#[test]
fn a_walk_writes_every_frame_an_animation_and_a_summary() {
    let scene = load(&scene_path("cornell-box"));
    let dir = tempfile::tempdir().unwrap();
    let bake_dir = dir.path().join("bake");
    bake_into(
        &scene,
        &bake_dir,
        &settings(64, 1),
        ends(&scene, &[0.0, 1.0]),
    );
    let out = dir.path().join("walk");
    let o = rangewalk(&[
        "walk",
        bake_dir.to_str().unwrap(),
        "--path",
        "walk",
        "--size",
        "24x16",
        "--fps",
        "4",
        "--time-interp",
        "reshade",
        "--check-every",
        "3",
        "--check-spp",
        "4",
        // A negative exposure is a value, not a flag.
        "--exposure",
        "-1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for i in 0..5 {
        let f = rangewalk::image::read_exr(out.join(format!("frame-{i:04}.exr"))).unwrap();
        assert_eq!((f.width, f.height), (24, 16));
        assert!(f.radiance.iter().all(|c| c.is_finite()));
        assert!(out.join(format!("frame-{i:04}.png")).exists());
    }
    assert!(!out.join("frame-0005.exr").exists());
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["frames"], 5);
    assert!(summary["frames_per_second"].as_f64().unwrap() > 0.0);
    // Frames 0 and 3 (every third) and 4 (the last) are checked: each
    // summary figure is the error of the written frame against the
    // written reference.
    let checks = summary["checks"].as_array().unwrap();
    let flip = rangewalk::eval::flip::Flip::locate()
        .unwrap_or_else(|e| panic!("FLIP is required by this test: {e:#}"));
    let mut maps = Vec::new();
    let checked: Vec<u64> = checks
        .iter()
        .map(|c| c["frame"].as_u64().unwrap())
        .collect();
    assert_eq!(checked, [0, 3, 4]);
    for c in checks {
        let i = c["frame"].as_u64().unwrap();
        let frame = rangewalk::image::read_exr(out.join(format!("frame-{i:04}.exr"))).unwrap();
        let reference =
            rangewalk::image::read_exr(out.join(format!("reference-{i:04}.exr"))).unwrap();
        assert_eq!(reference.meta.time, frame.meta.time);
        let e = rangewalk::eval::metrics::compare(&frame, &reference, None).unwrap();
        let close = |key: &str, v: f64| {
            let got = c[key].as_f64().unwrap();
            assert!(
                (got - v).abs() <= 1e-9 * v.abs().max(1.0),
                "{key}: {got} against {v}"
            );
        };
        close("lrms", e.lrms);
        close("bias", e.bias);
        close("block_lrms", e.block_lrms);
        close("block_p99", e.block_p99);
        let f = flip
            .hdr_maps(24, 16, &[(&reference.radiance, &frame.radiance)])
            .unwrap()
            .remove(0);
        close("flip", f.mean);
        maps.push(f.rgb);
    }
    assert!(!out.join("reference-0001.exr").exists());
    // Three columns of 24 pixels and three rows of 16, 4-pixel gaps: the
    // bottom row is FLIP's error map of each checked frame.
    let (width, height, sheet) = png_bytes(&out.join("contact.png"));
    assert_eq!((width, height), (3 * 24 + 2 * 4, 3 * 16 + 2 * 4));
    for (k, map) in maps.iter().enumerate() {
        for y in 0..16 {
            let at = ((2 * (16 + 4) + y) * width as usize + k * (24 + 4)) * 3;
            assert_eq!(
                &sheet[at..at + 24 * 3],
                &map[y * 24 * 3..(y + 1) * 24 * 3],
                "frame {k}, row {y}"
            );
        }
    }
    let line = String::from_utf8_lossy(&o.stdout);
    for what in [
        "mean LRMS",
        "mean 8x8-block LRMS",
        "mean block p99",
        "mean FLIP",
        "FLIP's error map (bottom",
    ] {
        assert!(line.contains(what), "{what}: {line}");
    }
    let apng = std::fs::read(out.join("walk.png")).unwrap();
    assert!(
        apng.windows(4).any(|w| w == b"acTL"),
        "walk.png is animated"
    );
    assert_eq!(
        apng.windows(4).filter(|w| w == b"fcTL").count(),
        5,
        "walk.png holds every frame"
    );
}

/// The width, height and 8-bit RGB bytes of a PNG as written.
fn png_bytes(path: &Path) -> (u32, u32, Vec<u8>) {
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

/// A walk's check measures FLIP unless told not to: without the Python
/// environment it fails before writing anything, naming the fix and the
/// way to do without; with `--no-flip` it says FLIP was left out and its
/// sheet has no error-map row.
#[test]
fn a_walk_check_without_flip_fails_or_says_it_left_flip_out() {
    let dir = tempfile::tempdir().unwrap();
    let (_, bake_dir) = tiny_bake(dir.path());
    let out = dir.path().join("walk");
    let walk = |extra: &[&str]| {
        let mut args = vec![
            "walk",
            bake_dir.to_str().unwrap(),
            "--path",
            "walk",
            "--size",
            "16x8",
            "--fps",
            "2",
            "--check-every",
            "2",
            "--check-spp",
            "2",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        Command::new(env!("CARGO_BIN_EXE_rangewalk"))
            .args(&args)
            .env("RANGEWALK_PYTHON", "/nonexistent/python")
            .output()
            .unwrap()
    };
    let o = walk(&[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("make deps")
            && err.contains("--no-flip")
            && err.contains("/nonexistent/python"),
        "{err}"
    );
    assert!(!out.exists() && !dir.path().join("walk.partial").exists());

    let o = walk(&["--no-flip"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let line = String::from_utf8_lossy(&o.stdout);
    assert!(
        line.contains("FLIP left out (--no-flip)") && !line.contains("mean FLIP"),
        "{line}"
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let checks = summary["checks"].as_array().unwrap();
    assert!(!checks.is_empty());
    assert!(checks
        .iter()
        .all(|c| c["flip"].is_null() && c["block_lrms"].is_f64()));
    let (_, height, _) = png_bytes(&out.join("contact.png"));
    assert_eq!(height, 2 * 8 + 4, "two rows without FLIP");

    // --no-flip means nothing without a check.
    let o = rangewalk(&[
        "walk",
        bake_dir.to_str().unwrap(),
        "--path",
        "walk",
        "--no-flip",
        "--out",
        "x",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("--check-every"),
        "{err}"
    );
}

/// A bake of the Cornell box small enough to make in a moment (16² bases
/// at its view space's ends, t = 0 and 1), in a folder of `dir`.
fn tiny_bake(dir: &Path) -> (Scene, PathBuf) {
    let scene = load(&scene_path("cornell-box"));
    let bake_dir = dir.join("bake");
    bake_into(
        &scene,
        &bake_dir,
        &settings(16, 1),
        ends(&scene, &[0.0, 1.0]),
    );
    (scene, bake_dir)
}

/// Counts that set the work of a pixel or of a walk are bounded, in the
/// library (so the C ABI has the same bounds) and at the command line:
/// each refusal names the flag, the value, the range and why, before any
/// output is made. `--light-rays 100000` asked for 10¹⁰ rays a pixel,
/// `--fps` in the thousands for a file per frame without end.
#[test]
fn counts_of_work_per_pixel_and_frames_per_walk_are_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, bake_dir) = tiny_bake(dir.path());
    let bake_s = bake_dir.to_str().unwrap();
    let out = dir.path().join("frame.exr");
    let out_s = out.to_str().unwrap();
    for (flag, value, needle) in [
        (
            "--light-rays",
            "100000",
            "--light-rays 100000 must lie in 0..=32",
        ),
        ("--light-rays", "33", "--light-rays 33 must lie in 0..=32"),
        (
            "--reshade-samples",
            "100000",
            "--reshade-samples 100000 must lie in 1..=256",
        ),
        (
            "--reshade-samples",
            "0",
            "--reshade-samples 0 must lie in 1..=256",
        ),
        ("--bases", "0", "--bases 0"),
        ("--tolerance", "1", "--tolerance 1 must lie in (0, 1)"),
    ] {
        let o = rangewalk(&[
            "synth", bake_s, "--time", "0.5", "--size", "8x8", flag, value, "--out", out_s,
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{flag} {value}: {err}");
        assert!(err.contains(needle), "{flag} {value}: {err}");
        assert!(!out.exists(), "{flag} {value} wrote a frame");
    }
    // The highest values allowed make a frame.
    let o = rangewalk(&[
        "synth",
        bake_s,
        "--time",
        "0.5",
        "--size",
        "8x8",
        "--light-rays",
        "32",
        "--time-interp",
        "reshade",
        "--reshade-samples",
        "256",
        "--out",
        out_s,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.exists());

    // The library refuses them too, whoever calls it.
    let baked = bake::Bake::open(&bake_dir, &scene).unwrap();
    let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
    let camera = scene.camera("main").unwrap().perspective(8, 8).unwrap();
    for (opts, needle) in [
        (
            Options {
                light_rays: 100_000,
                ..Options::default()
            },
            "options.light_rays 100000",
        ),
        (
            Options {
                reshade_samples: 1 << 20,
                ..Options::default()
            },
            "options.reshade_samples 1048576",
        ),
    ] {
        let msg = format!("{:#}", synth.frame(&camera, 0.5, &opts).unwrap_err());
        assert!(msg.contains(needle), "{msg}");
    }

    // A walk of more frames than a walk writes: refused before the first.
    let walk_out = dir.path().join("walk");
    let o = rangewalk(&[
        "walk",
        bake_s,
        "--path",
        "walk",
        "--size",
        "4x4",
        "--fps",
        "20000",
        "--out",
        walk_out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("--fps 20000") && err.contains("20001 frames") && err.contains("10000"),
        "{err}"
    );
    assert!(!walk_out.exists() && !dir.path().join("walk.partial").exists());
}

/// A frame too large for memory is an error that says how much it needs,
/// not an abort: under a 1.5 GB address-space limit, an 8192² frame (2²
/// subpixels by default: 268 M subpixels, 12.9 GB of z-buffer) is refused
/// by its size, subpixels counted, and a 4096² one, within the size limit,
/// fails to allocate its 3.2 GB z-buffer and says so. Neither leaves a
/// file.
#[test]
fn a_frame_too_large_for_memory_is_an_error_saying_how_much_it_needs() {
    let dir = tempfile::tempdir().unwrap();
    let (_, bake_dir) = tiny_bake(dir.path());
    let out = dir.path().join("frame.exr");
    for (size, needles) in [
        (
            "8192x8192",
            ["268435456 subpixels", "12.9 GB", "--supersample"],
        ),
        (
            "4096x4096",
            ["z-buffer", "needs 3.2 GB", "allocation failed"],
        ),
    ] {
        let o = Command::new("sh")
            .arg("-c")
            .arg(r#"ulimit -v 1500000 && exec "$0" "$@""#)
            .arg(env!("CARGO_BIN_EXE_rangewalk"))
            .args(["synth", bake_dir.to_str().unwrap(), "--time", "0.5"])
            .args(["--size", size, "--out", out.to_str().unwrap()])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{size}: {err}");
        for needle in needles {
            assert!(err.contains(needle), "{size}: `{needle}` not in {err}");
        }
        for abort in ["memory allocation of", "backtrace", "panicked"] {
            assert!(!err.contains(abort), "{size}: {err}");
        }
        assert!(!out.exists(), "{size}");
    }
}

/// RMS over the 8 × 8 blocks that lie mostly (three quarters) on `mask`
/// of the block means' luminance difference, relative to the reference's
/// mean luminance, and how many blocks: the structure a viewer sees (a
/// seam, a patch of wrong light) without the pixels' noise.
fn block_error(frame: &RangeImage, reference: &RangeImage, mask: &[bool]) -> (f64, usize) {
    let (w, h) = (reference.width as usize, reference.height as usize);
    let y = |img: &RangeImage, k: usize| luminance(img.radiance[k]) as f64;
    let mean = (0..reference.len()).map(|k| y(reference, k)).sum::<f64>() / reference.len() as f64;
    let mut errors = Vec::new();
    for by in 0..h / 8 {
        for bx in 0..w / 8 {
            let block: Vec<usize> = (0..64)
                .map(|i| (by * 8 + i / 8) * w + bx * 8 + i % 8)
                .collect();
            if block.iter().filter(|&&k| mask[k]).count() < 48 {
                continue;
            }
            let m = |img: &RangeImage| block.iter().map(|&k| y(img, k)).sum::<f64>() / 64.0;
            errors.push((m(frame) - m(reference)) / mean);
        }
    }
    let n = errors.len();
    (
        (errors.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt(),
        n,
    )
}

/// Between base times a surface seen at only one of them (what a moving
/// box uncovered) carries that time's light, the pixels beside it the
/// blend of both: a seam crossed the tall box at the short box's height.
/// Re-shading corrects diffuse indirect light by the bake's radiosity
/// records, so the moving boxes are as right between base times as at
/// one. The reference is a multipass render with the same records, so
/// that only synthesis is measured, not the records' own error.
#[test]
fn between_base_times_the_moving_boxes_are_as_right_as_at_a_base_time() {
    let scene = load(&scene_path("cornell-box"));
    let dir = tempfile::tempdir().unwrap();
    let main = scene.camera("main").unwrap();
    let camera = main.perspective(128, 128).unwrap();
    // Bases of the size rule's pixels: a base pixel holds one object's
    // light, so edges between objects are as fine as its pixels.
    let Projection::Perspective { vfov_deg } = camera.projection else {
        panic!("the main camera is a pinhole");
    };
    let size = bake::size::base_size(BaseProjection::Sphere, (128, 128), vfov_deg);
    let with_records = Settings {
        indirect: IndirectSource::Radiosity,
        ..settings(size, 16)
    };
    let baked = bake_into(&scene, dir.path(), &with_records, ends(&scene, &[0.0, 1.0]));
    let (simplified, series) =
        rangewalk::radiosity::store::load(&dir.path().join("radiosity")).unwrap();
    let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
    let opts = Options {
        time_interp: TimeInterp::Reshade,
        ..Options::default()
    };
    let mut at = |t: f32| {
        let cache = IrradianceCache::new(&simplified, &series.indirect_at(t)).unwrap();
        let e = engine(&scene, t);
        let s = RenderSettings {
            spp: 256,
            max_depth: None,
            seed: 11,
        };
        let reference = render::multipass::render(&scene, e.as_ref(), &camera, t, &s, &cache)
            .unwrap()
            .0;
        let boxes: Vec<bool> = reference
            .object_id
            .iter()
            .map(|&o| o == 6 || o == 7)
            .collect();
        let (frame, stats) = synth.frame(&camera, t, &opts).unwrap();
        assert!(stats.indirect_corrected, "t = {t}: records unused");
        block_error(&frame, &reference, &boxes)
    };
    let (at_base, n) = at(0.0);
    let (between, _) = at(0.5);
    // The RMS of n block errors is known to a relative standard error of
    // about 1/sqrt(2 n); two of them allow for the base time's own.
    let allowed = at_base * (1.0 + 2.0 / (2.0 * n as f64).sqrt());
    assert!(
        between <= allowed,
        "8x8-block error on the moving boxes: {between:.4} at t = 0.5, {at_base:.4} at t = 0 \
         ({n} blocks), at most {allowed:.4}"
    );
}

/// The Cornell box baked at its view space's ends at t = 0 and 1 (512²
/// sphere bases of `spp` samples), and its `main` camera at 128²: half way
/// the boxes have moved by 112 mm and 15 degrees.
fn boxes_between_ends(spp: u32) -> (Scene, tempfile::TempDir, bake::Bake, Camera) {
    let scene = load(&scene_path("cornell-box"));
    let dir = tempfile::tempdir().unwrap();
    let baked = bake_into(
        &scene,
        dir.path(),
        &settings(512, spp),
        ends(&scene, &[0.0, 1.0]),
    );
    let camera = scene.camera("main").unwrap().perspective(128, 128).unwrap();
    (scene, dir, baked, camera)
}

/// No frame pixel a pixel away from every silhouette shows another
/// surface than a render's. Objects that move apart tear the surface
/// between them: splats bridged neighbours of different objects close in
/// depth, so the short box, sliding away from the floor and the tall box,
/// was stretched over both. And a base's sky pixels, projected by their
/// direction alone, claimed gaps in the tall box's samples as black dots.
#[test]
fn objects_that_move_apart_keep_their_own_pixels() {
    let (scene, _dir, baked, camera) = boxes_between_ends(4);
    let t = 0.5;
    let reference = path_traced(&scene, &camera, t, 1);
    let (w, h) = (128usize, 128usize);
    // Pixels whose 3 × 3 neighbourhood shows one object in the reference:
    // off every silhouette by at least a pixel.
    let inside = |k: usize| {
        let (x, y) = (k % w, k / w);
        x > 0
            && y > 0
            && x + 1 < w
            && y + 1 < h
            && (0..9).all(|i| {
                reference.object_id[(y + i / 3 - 1) * w + x + i % 3 - 1] == reference.object_id[k]
            })
    };
    let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
    for time_interp in [TimeInterp::Motion, TimeInterp::Reshade] {
        let opts = Options {
            time_interp,
            ..Options::default()
        };
        let frame = synth.frame(&camera, t, &opts).unwrap().0;
        let wrong: Vec<(usize, usize, u32, u32)> = (0..reference.len())
            .filter(|&k| inside(k) && frame.object_id[k] != reference.object_id[k])
            .map(|k| (k % w, k / w, frame.object_id[k], reference.object_id[k]))
            .collect();
        assert!(
            wrong.is_empty(),
            "{time_interp:?}: {} pixels off every silhouette show another object than a render \
             (x, y, frame's object, render's): {:?}",
            wrong.len(),
            &wrong[..wrong.len().min(20)]
        );
    }
}

/// The animated Cornell box in which every surface only emits, each
/// material its own colour and the short box a colour of its own: a pixel
/// shows exactly the light of what it sees, with no noise, so a frame
/// pixel that takes another object's light is found to the last bit.
fn glowing_boxes(dir: &Path) -> Scene {
    let copy = dir.join("scene");
    std::fs::create_dir(&copy).unwrap();
    let source = scene_path("cornell-box");
    std::fs::copy(
        source.with_file_name("cornell-box.obj"),
        copy.join("cornell-box.obj"),
    )
    .unwrap();
    let mut text = std::fs::read_to_string(&source).unwrap();
    for (name, glow) in [
        ("white", "[0.5, 0.5, 0.5]"),
        ("red", "[0.6, 0.05, 0.05]"),
        ("green", "[0.05, 0.5, 0.05]"),
    ] {
        let was = format!("name = \"{name}\"\ntype = \"diffuse\"\n");
        assert!(text.contains(&was), "the Cornell box has material `{name}`");
        text = text.replace(
            &was,
            &format!("{was}emission = {glow}\ntwo_sided_emission = true\n"),
        );
    }
    let short = "group = \"short-box\"\nmaterial = \"white\"";
    assert!(text.contains(short), "the Cornell box has a short box");
    text = text.replace(short, "group = \"short-box\"\nmaterial = \"blue\"")
        + "\n[[materials]]\nname = \"blue\"\ntype = \"diffuse\"\nreflectance = [0, 0, 0]\n\
           emission = [0.05, 0.05, 2]\ntwo_sided_emission = true\n";
    let text: String = text
        .lines()
        .map(|l| {
            if l.starts_with("reflectance") {
                "reflectance = [0, 0, 0]\n".to_string()
            } else {
                format!("{l}\n")
            }
        })
        .collect();
    std::fs::write(copy.join("scene.toml"), text).unwrap();
    load(&copy.join("scene.toml"))
}

/// A base pixel beside another object holds some of that object's light.
/// Where the two move apart between base times, the pixel took that light
/// along with its own object: the short box's bright top edge was drawn as
/// a line across the tall box and the wall behind it. In a scene of
/// emitters every pixel off the silhouettes must show exactly its own
/// object's light, at a base time and between.
#[test]
fn a_pixel_off_the_silhouettes_holds_only_its_own_objects_light() {
    let dir = tempfile::tempdir().unwrap();
    let scene = glowing_boxes(dir.path());
    let baked = bake_into(
        &scene,
        &dir.path().join("bake"),
        &settings(512, 4),
        ends(&scene, &[0.0, 1.0]),
    );
    let camera = scene.camera("main").unwrap().perspective(128, 128).unwrap();
    let (w, h) = (128usize, 128usize);
    let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
    let mut failures = Vec::new();
    for t in [0.0, 0.5] {
        let reference = path_traced(&scene, &camera, t, 1);
        // Off every silhouette by two pixels in the render: a base pixel
        // there spans 1.2 of the frame's, and a frame pixel averages what
        // covers it.
        let inside = |k: usize| {
            let (x, y) = (k % w, k / w);
            x > 1
                && y > 1
                && x + 2 < w
                && y + 2 < h
                && (0..25).all(|i| {
                    reference.object_id[(y + i / 5 - 2) * w + x + i % 5 - 2]
                        == reference.object_id[k]
                })
        };
        for time_interp in [TimeInterp::Motion, TimeInterp::Reshade] {
            let opts = Options {
                time_interp,
                ..Options::default()
            };
            let frame = synth.frame(&camera, t, &opts).unwrap().0;
            let wrong: Vec<(usize, usize, Vec3, Vec3)> = (0..reference.len())
                .filter(|&k| {
                    inside(k)
                        && reference.object_id[k] != NO_HIT
                        && !(frame.radiance[k] - reference.radiance[k])
                            .abs()
                            .cmple(reference.radiance[k] * 4.0 * HALF + Vec3::splat(1e-4))
                            .all()
                })
                .map(|k| (k % w, k / w, frame.radiance[k], reference.radiance[k]))
                .collect();
            if !wrong.is_empty() {
                failures.push(format!(
                    "t = {t}, {time_interp:?}: {} pixels off every silhouette hold other light \
                     than their object's (x, y, frame, render): {:?}",
                    wrong.len(),
                    &wrong[..wrong.len().min(12)]
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A silhouette against the sky (the Cornell box's walls seen past their
/// front edges) follows the base's pixel grid, turned and stretched by
/// reprojection, as a jagged, dotted edge; a render's pixels hold each
/// side's share. Traced at the frame's own pixels, the edge is no worse
/// than a render taking the bases' own samples a pixel.
#[test]
fn silhouettes_carry_a_renders_antialiasing() {
    let (scene, _dir, baked, camera) = boxes_between_ends(16);
    let t = 0.5;
    let reference = path_traced(&scene, &camera, t, 1024);
    let (w, h) = (128i64, 128i64);
    let near = |k: usize, r: i64, what: &dyn Fn(u32) -> bool| {
        let (x, y) = ((k as i64) % w, (k as i64) / w);
        (-r..=r).any(|dy| {
            (-r..=r).any(|dx| {
                let (u, v) = (x + dx, y + dy);
                u >= 0
                    && v >= 0
                    && u < w
                    && v < h
                    && what(reference.object_id[(v * w + u) as usize])
            })
        })
    };
    // Surface pixels beside the sky, away from the light's rim.
    let light = scene
        .objects
        .iter()
        .position(|o| o.name == "light")
        .unwrap() as u32;
    let edge: Vec<bool> = (0..reference.len())
        .map(|k| {
            reference.object_id[k] != NO_HIT
                && near(k, 1, &|o| o == NO_HIT)
                && !near(k, 3, &|o| o == light)
        })
        .collect();
    assert!(
        edge.iter().filter(|&&e| e).count() > 200,
        "the walls' edges are in view"
    );
    let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
    let opts = Options {
        time_interp: TimeInterp::Reshade,
        ..Options::default()
    };
    let frame = synth.frame(&camera, t, &opts).unwrap().0;
    let (synthesized, rendered) = (
        error(&frame, &reference, &edge),
        error(
            &path_traced_with_seed(&scene, &camera, t, 16, 99),
            &reference,
            &edge,
        ),
    );
    eprintln!(
        "silhouettes against the sky: synthesized {synthesized:.4}, 16-spp render {rendered:.4}"
    );
    assert!(
        synthesized <= rendered,
        "at silhouettes against the sky: synthesized {synthesized:.4}, a 16-spp render (the bases' samples) {rendered:.4}"
    );
}

/// The Cornell box's view-space ends at both ends of its animation, baked
/// whole and cropped to what the bases may see, into `dir/whole` and
/// `dir/partial`.
fn whole_and_partial(
    scene: &Scene,
    dir: &Path,
    size: u32,
    projection: BaseProjection,
) -> (bake::Bake, bake::Bake) {
    let plan = || ends(scene, &[0.0, 1.0]);
    let partial = Settings {
        projection,
        ..settings(size, 1)
    };
    let mut whole = partial;
    whole.planning.whole = true;
    (
        bake_into(scene, &dir.join("whole"), &whole, plan()),
        bake_into(scene, &dir.join("partial"), &partial, plan()),
    )
}

#[test]
fn a_partial_bake_makes_the_frames_of_a_whole_one_bit_for_bit() {
    for projection in [BaseProjection::Sphere, BaseProjection::Fisheye] {
        partial_frames_are_whole_frames(projection);
    }
}

fn partial_frames_are_whole_frames(projection: BaseProjection) {
    let scene = load(&scene_path("cornell-box"));
    let dir = tempfile::tempdir().unwrap();
    // 384: the box covers the middle third of the image's side, so the
    // windows start past the first 128-pixel block and end before the edge.
    let size = 384;
    let (whole, partial) = whole_and_partial(&scene, dir.path(), size, projection);
    for (v, w) in partial.manifest.windows.iter().enumerate() {
        assert!(
            w.pixels() * 2 < u64::from(size * size) && (w.x, w.y) != (0, 0),
            "{projection}, view {v}: window {w} of {size}x{size} does not test cropping"
        );
    }
    let Some(rangewalk::scene::ViewSpace::Segment { a, b }) = scene.view_space else {
        panic!("the Cornell box's view space is a segment");
    };
    let main = scene.camera("main").unwrap();
    // Across the view space (its ends, between them), looking into the
    // box, past its sides and top edge into the sky, and away from it.
    let mut cameras = Vec::new();
    for s in [0.0, 0.3, 1.0] {
        let at = a.lerp(b, s);
        for (yaw, pitch) in [
            (0.0f32, 0.0f32),
            (24.0, 0.0),
            (-24.0, 8.0),
            (0.0, 18.0),
            (180.0, 0.0),
        ] {
            let d = glam::Quat::from_rotation_y(yaw.to_radians())
                * glam::Quat::from_rotation_x(-pitch.to_radians())
                * main.direction;
            let p = Projection::Perspective {
                vfov_deg: main.vfov_deg,
            };
            cameras.push(Camera::looking(at, d, main.up, p, 48, 48).unwrap());
        }
    }
    let variants = [
        ("defaults", Options::default()),
        (
            "foreground fill (sky splatted), untraced",
            Options {
                fill: Fill::Foreground,
                light_rays: 0,
                ..Options::default()
            },
        ),
        (
            "foreground fill (sky splatted)",
            Options {
                fill: Fill::Foreground,
                ..Options::default()
            },
        ),
        (
            "nearest first",
            Options {
                blend: Blend::Nearest,
                ..Options::default()
            },
        ),
        (
            "linear in time",
            Options {
                time_interp: TimeInterp::Linear,
                ..Options::default()
            },
        ),
        (
            "re-shaded",
            Options {
                time_interp: TimeInterp::Reshade,
                ..Options::default()
            },
        ),
    ];
    let mut a_synth = Synthesizer::new(&scene, &whole, DEFAULT_BUDGET);
    let mut b_synth = Synthesizer::new(&scene, &partial, DEFAULT_BUDGET);
    let mut sky = 0;
    for (name, opts) in &variants {
        for (c, camera) in cameras.iter().enumerate() {
            for t in [0.0, 0.4, 1.0] {
                let (want, _) = a_synth.frame(camera, t, opts).unwrap();
                let (got, _) = b_synth.frame(camera, t, opts).unwrap();
                let same = |k: usize| {
                    want.radiance[k].to_array().map(f32::to_bits)
                        == got.radiance[k].to_array().map(f32::to_bits)
                        && want.object_id[k] == got.object_id[k]
                        && want.distance[k].to_bits() == got.distance[k].to_bits()
                };
                let differ: Vec<usize> = (0..want.len()).filter(|&k| !same(k)).collect();
                if let Some(&k) = differ.first() {
                    panic!(
                        "{projection}, {name}, camera {c} at {} looking {}, t = {t}: {} pixels differ; \
                         first ({}, {}): whole {} (object {}), partial {} (object {})",
                        camera.position,
                        camera.forward,
                        differ.len(),
                        k % 48,
                        k / 48,
                        want.radiance[k],
                        want.object_id[k],
                        got.radiance[k],
                        got.object_id[k]
                    );
                }
                sky += want.object_id.iter().filter(|&&o| o == NO_HIT).count();
            }
        }
    }
    assert!(sky > 0, "{projection}: no frame saw the sky beside the box");
}
