//! Base-image bakes: images agree with direct renders, bakes resume and
//! shard to exactly the single-machine result, and are refused for a scene
//! that changed.

use std::path::Path;

use glam::Vec3;
use rangewalk::accel::Backend;
use rangewalk::bake::{self, size, BaseProjection, IndirectSource, Settings, Shard};
use rangewalk::camera::{Camera, Projection};
use rangewalk::eval::metrics::luminance;
use rangewalk::image::{exr_content_hash, NO_HIT};
use rangewalk::plan::{Plan, PlannedView};
use rangewalk::quality::Quality;
use rangewalk::render::multipass::{self, Indirect};
use rangewalk::render::{self, Progress, RenderSettings};
use rangewalk::scene::Scene;

mod common;
use common::{engine, load_path as load, scene_path};

/// Two views at the ends of the Cornell box's view space, at two times:
/// what the planner gives at low quality, without depending on it.
fn two_by_two(scene: &Scene) -> Plan {
    let Some(rangewalk::scene::ViewSpace::Segment { a, b }) = scene.view_space else {
        panic!("the Cornell box's view space is a segment");
    };
    let a_ = scene.animation;
    Plan {
        quality: Quality::new(0.3).unwrap(),
        views: [a, b]
            .map(|position| PlannedView {
                position,
                times: vec![a_.start, a_.end],
            })
            .to_vec(),
        light_times: vec![a_.start, a_.end],
        ..Plan::default()
    }
}

fn tiny(indirect: IndirectSource) -> Settings {
    Settings {
        quality: Quality::new(0.3).unwrap(),
        size: 48,
        spp: 2,
        projection: BaseProjection::Sphere,
        indirect,
        seed: 5,
        backend: Backend::Bvh,
        max_depth: None,
        planning: Default::default(),
    }
}

fn bake_into(scene: &Scene, dir: &Path, settings: &Settings, shard: Shard) -> bake::Summary {
    let mut e = engine(scene, settings.backend);
    let plan = two_by_two(scene);
    bake::run(scene, dir, settings, shard, e.as_mut(), |_| Ok(plan))
        .unwrap_or_else(|e| panic!("{e:#}"))
}

/// Each image's file and a hash of every bit of its channels and metadata.
fn image_contents(dir: &Path) -> Vec<(String, u64)> {
    let m = bake::Manifest::read(dir).unwrap();
    m.images
        .iter()
        .map(|e| (e.file.clone(), exr_content_hash(dir.join(&e.file)).unwrap()))
        .collect()
}

#[test]
fn shards_together_make_the_single_machine_bake_bit_for_bit() {
    let scene = load(&scene_path("cornell-box"));
    let tmp = tempfile::tempdir().unwrap();
    let (whole, sharded) = (tmp.path().join("whole"), tmp.path().join("sharded"));
    let settings = tiny(IndirectSource::Radiosity);
    let s = bake_into(&scene, &whole, &settings, Shard::ALL);
    assert_eq!((s.rendered, s.total, s.complete), (4, 4, true));
    for index in 0..3 {
        let s = bake_into(&scene, &sharded, &settings, Shard { index, count: 3 });
        assert_eq!(s.complete, index == 2, "shard {index}: {s:?}");
        assert_eq!(s.rendered, [2, 1, 1][index as usize]);
    }
    assert_eq!(image_contents(&whole), image_contents(&sharded));
    assert_eq!(
        bake::Manifest::read(&whole).unwrap(),
        bake::Manifest::read(&sharded).unwrap()
    );
    // A finished bake started again renders nothing.
    let again = bake_into(&scene, &whole, &settings, Shard::ALL);
    assert_eq!((again.rendered, again.reused), (0, 4));
}

#[test]
fn missing_and_damaged_images_are_rendered_again_and_nothing_else() {
    let scene = load(&scene_path("cornell-box"));
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("bake");
    let settings = tiny(IndirectSource::Path);
    bake_into(&scene, &dir, &settings, Shard::ALL);
    let before = image_contents(&dir);
    let m = bake::Manifest::read(&dir).unwrap();
    // One image gone, one changed where it still reads (a letter of its
    // header's provenance text: a damage no decoder notices), one cut short.
    std::fs::remove_file(dir.join(&m.images[0].file)).unwrap();
    let mut bytes = std::fs::read(dir.join(&m.images[1].file)).unwrap();
    let at = bytes
        .windows(9)
        .position(|w| w == b"multipass")
        .expect("the header names the renderer");
    bytes[at] = b'M';
    std::fs::write(dir.join(&m.images[1].file), &bytes).unwrap();
    let third = std::fs::read(dir.join(&m.images[2].file)).unwrap();
    std::fs::write(dir.join(&m.images[2].file), &third[..100]).unwrap();
    let opened = bake::Bake::open(&dir, &scene).unwrap();
    let Err(err) = opened.read(1) else {
        panic!("a damaged image is read as if whole");
    };
    assert!(format!("{err:#}").contains("damaged"), "{err:#}");

    let s = bake_into(&scene, &dir, &settings, Shard::ALL);
    assert_eq!((s.rendered, s.reused), (3, 1), "{s:?}");
    assert_eq!(image_contents(&dir), before);
}

#[test]
fn a_bake_is_refused_for_a_changed_or_scaled_scene_saying_what_changed() {
    let tmp = tempfile::tempdir().unwrap();
    let copy = tmp.path().join("scene");
    std::fs::create_dir(&copy).unwrap();
    for f in ["scene.toml", "cornell-box.obj"] {
        std::fs::copy(scene_path("cornell-box").with_file_name(f), copy.join(f)).unwrap();
    }
    let scene = load(&copy.join("scene.toml"));
    let dir = tmp.path().join("bake");
    let settings = tiny(IndirectSource::Path);
    bake_into(&scene, &dir, &settings, Shard::ALL);
    bake::Bake::open(&dir, &scene).expect("the bake fits its own scene");

    // The scaled copy of the scene: other text, other meshes.
    let scaled = load(&scene_path("cornell-box-1e4"));
    let err = format!(
        "{:#}",
        bake::Bake::open(&dir, &scaled).expect_err("refused")
    );
    assert!(
        err.contains("text") && err.contains("object `floor` changed"),
        "{err}"
    );

    // An edited light: the text and the material.
    let text = std::fs::read_to_string(copy.join("scene.toml")).unwrap();
    let edited = text.replace("emission = [17, 12, 4]", "emission = [17, 12, 5]");
    assert_ne!(text, edited);
    std::fs::write(copy.join("scene.toml"), edited).unwrap();
    let changed = load(&copy.join("scene.toml"));
    let err = format!(
        "{:#}",
        bake::Bake::open(&dir, &changed).expect_err("refused")
    );
    assert!(err.contains("material `light` changed"), "{err}");
    // Resuming it is refused too, and so is resuming with other settings.
    let mut e = engine(&changed, Backend::Bvh);
    let plan = two_by_two(&changed);
    let err = bake::run(&changed, &dir, &settings, Shard::ALL, e.as_mut(), |_| {
        Ok(plan)
    });
    assert!(err.is_err());
    let more = Settings { spp: 4, ..settings };
    let mut e = engine(&scene, Backend::Bvh);
    let plan = two_by_two(&scene);
    std::fs::write(copy.join("scene.toml"), &text).unwrap();
    let scene = load(&copy.join("scene.toml"));
    let err = bake::run(&scene, &dir, &more, Shard::ALL, e.as_mut(), |_| Ok(plan))
        .expect_err("other settings are refused");
    assert!(format!("{err:#}").contains("--spp 2, not 4"), "{err:#}");
}

#[test]
fn base_images_hold_their_layers_and_first_hits() {
    let scene = load(&scene_path("cornell-box"));
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("bake");
    let settings = Settings {
        size: 64,
        spp: 4,
        ..tiny(IndirectSource::Radiosity)
    };
    bake_into(&scene, &dir, &settings, Shard::ALL);
    let b = bake::Bake::open(&dir, &scene).unwrap();
    for k in 0..b.manifest.images.len() {
        let base = b.read(k).unwrap();
        let img = &base.image;
        assert_eq!(img.meta.camera.projection, Projection::Sphere);
        let window = b.manifest.windows[b.manifest.images[k].view];
        assert_eq!((img.width, img.height), (window.width, window.height));
        assert_eq!(img.meta.camera.full_size(), (64, 64));
        let e = &b.manifest.images[k];
        assert_eq!(img.meta.time, e.time);
        assert_eq!(
            img.meta.camera.position,
            b.manifest.plan.views[e.view].position
        );
        let mut indirect_sum = 0.0;
        for i in 0..img.len() {
            let sum = base.direct[i] + base.indirect[i];
            assert!(
                (sum - img.radiance[i]).abs().max_element()
                    <= 1e-4 * img.radiance[i].max_element().max(1e-3)
            );
            assert!(base.indirect[i].min_element() >= 0.0);
            indirect_sum += luminance(base.indirect[i]);
        }
        // Looking into the box from outside, most of the sphere sees it lit
        // by bounced light as well as directly.
        assert!(indirect_sum > 0.0, "image {k} has no indirect light");
    }
}

/// Mean luminance over `b × b` blocks, row-major.
fn blocks(img: &[Vec3], w: usize, b: usize) -> Vec<f64> {
    let h = img.len() / w;
    let mut out = Vec::new();
    for by in 0..h / b {
        for bx in 0..w / b {
            let mut s = 0.0;
            for y in by * b..(by + 1) * b {
                for x in bx * b..(bx + 1) * b {
                    s += luminance(img[y * w + x]);
                }
            }
            out.push(s / (b * b) as f64);
        }
    }
    out
}

fn relative_rms(a: &[f64], b: &[f64]) -> f64 {
    let mean = b.iter().sum::<f64>() / b.len() as f64;
    let ms = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>() / a.len() as f64;
    ms.sqrt() / mean
}

#[test]
fn a_sphere_base_image_resampled_into_a_pinhole_view_agrees_with_a_pinhole_render() {
    let scene = load(&scene_path("cornell-box"));
    let n = 64u32;
    let pinhole = scene.camera("main").unwrap().perspective(n, n).unwrap();
    let vfov = scene.camera("main").unwrap().vfov_deg;
    // Twice as fine as the rule asks, at a quarter of the samples per pixel:
    // each frame pixel then gathers about as many samples as the reference's
    // (256, so that the noise of the mean, ~0.3%, leaves the 1% bound on
    // the bias room).
    let side = 2 * size::base_size(BaseProjection::Sphere, (n, n), vfov);
    let sphere = Camera::looking(
        pinhole.position,
        pinhole.forward,
        pinhole.up,
        Projection::Sphere,
        side,
        side,
    )
    .unwrap();
    let e = engine(&scene, Backend::default_available());
    let s = |spp, seed| RenderSettings {
        spp,
        max_depth: None,
        seed,
    };
    let base = multipass::render_layers(
        &scene,
        e.as_ref(),
        &sphere,
        0.0,
        &s(64, 1),
        Indirect::Traced,
        None,
        Progress::Tiles,
    )
    .unwrap();
    let reference = render::render(&scene, e.as_ref(), &pinhole, 0.0, &s(256, 2))
        .unwrap()
        .0;
    let second = render::render(&scene, e.as_ref(), &pinhole, 0.0, &s(256, 3))
        .unwrap()
        .0;

    // Each frame pixel: the base pixels under an 8 x 8 grid of its rays.
    let k = 8;
    let mut resampled = Vec::with_capacity((n * n) as usize);
    for y in 0..n {
        for x in 0..n {
            let mut sum = Vec3::ZERO;
            for j in 0..k {
                for i in 0..k {
                    let ray = pinhole
                        .ray(
                            x as f32 + (i as f32 + 0.5) / k as f32,
                            y as f32 + (j as f32 + 0.5) / k as f32,
                        )
                        .unwrap();
                    let p = sphere.project(sphere.position + ray.dir).unwrap();
                    let (px, py) = ((p.x as u32).min(side - 1), (p.y as u32).min(side - 1));
                    sum += base.image.radiance[(py * side + px) as usize];
                }
            }
            resampled.push(sum / (k * k) as f32);
        }
    }
    let mean = |v: &[Vec3]| v.iter().map(|&c| luminance(c)).sum::<f64>() / v.len() as f64;
    let bias = mean(&resampled) / mean(&reference.radiance) - 1.0;
    assert!(
        bias.abs() < 0.01,
        "resampled mean differs by {:.2}%",
        100.0 * bias
    );
    // Resampling blurs by up to half a base pixel: harmless except at the
    // light's outline, where a 300:1 step moves light between blocks. The
    // blocks the outline crosses are compared by their total (light may
    // move within them, not leave them); the rest block by block.
    let w = n as usize;
    let light = scene
        .objects
        .iter()
        .position(|o| o.name == "light")
        .unwrap() as u32;
    let b = 8;
    // Pixels on the light or next to it (a pixel whose centre misses the
    // light may still be partly covered by it).
    let near_light = |x: usize, y: usize| {
        (y.saturating_sub(1)..(y + 2).min(w)).any(|v| {
            (x.saturating_sub(1)..(x + 2).min(w)).any(|u| reference.object_id[v * w + u] == light)
        })
    };
    let outline: Vec<bool> = (0..(w / b) * (w / b))
        .map(|k| {
            let (bx, by) = (k % (w / b), k / (w / b));
            let near = (by * b..(by + 1) * b)
                .flat_map(|y| (bx * b..(bx + 1) * b).map(move |x| (x, y)))
                .filter(|&(x, y)| near_light(x, y))
                .count();
            near > 0
        })
        .collect();
    assert!(outline.iter().any(|&o| o), "the light is in view");
    let split = |img: &[Vec3]| {
        let v = blocks(img, w, b);
        let edge: f64 = v
            .iter()
            .zip(&outline)
            .filter(|(_, &o)| o)
            .map(|(x, _)| x)
            .sum();
        let rest: Vec<f64> = v
            .iter()
            .zip(&outline)
            .filter(|(_, &o)| !o)
            .map(|(&x, _)| x)
            .collect();
        (edge, rest)
    };
    let (ref_edge, ref_rest) = split(&reference.radiance);
    let (second_edge, second_rest) = split(&second.radiance);
    let (res_edge, res_rest) = split(&resampled);
    let floor = relative_rms(&second_rest, &ref_rest);
    let err = relative_rms(&res_rest, &ref_rest);
    // Two independent estimates of equal variance differ by the noise floor;
    // its estimate from ~60 blocks is good to about 10%, so 1.5x it leaves
    // room for sampling luck but not for a misplaced or blurred image.
    assert!(
        err < 1.5 * floor,
        "block RMS {err:.4} against a noise floor of {floor:.4}"
    );
    let edge_floor = (second_edge / ref_edge - 1.0).abs();
    let edge_err = (res_edge / ref_edge - 1.0).abs();
    println!(
        "bias {:.3}% (two references differ by {:.3}%), block RMS {err:.4} (noise {floor:.4}), outline {:.2}% (noise {:.2}%)",
        100.0 * bias,
        100.0 * (mean(&second.radiance) / mean(&reference.radiance) - 1.0),
        100.0 * edge_err,
        100.0 * edge_floor
    );
    assert!(
        edge_err < 0.01 + 3.0 * edge_floor,
        "light outline: {:.2}% off (noise {:.2}%)",
        100.0 * edge_err,
        100.0 * edge_floor
    );
}

#[test]
fn shards_parse_and_split_every_image_once() {
    assert_eq!("2/5".parse::<Shard>(), Ok(Shard { index: 2, count: 5 }));
    for bad in ["5/5", "1/0", "x/2", "3", "-1/2"] {
        assert!(bad.parse::<Shard>().is_err(), "{bad}");
    }
    for count in 1..5 {
        for k in 0..20 {
            let owners = (0..count)
                .filter(|&index| Shard { index, count }.owns(k))
                .count();
            assert_eq!(owners, 1);
        }
    }
}

#[test]
fn shards_of_one_bake_run_together_and_other_runs_on_their_images_are_refused() {
    let scene = &load(&scene_path("cornell-box"));
    let tmp = tempfile::tempdir().unwrap();
    let dir = &tmp.path().join("bake");
    let settings = &tiny(IndirectSource::Path);
    let try_bake = |settings: &Settings, shard| {
        let mut e = engine(scene, settings.backend);
        let plan = two_by_two(scene);
        bake::run(scene, dir, settings, shard, e.as_mut(), |_| Ok(plan))
    };
    let (paused, wait_paused) = std::sync::mpsc::channel();
    let (go, wait_go) = std::sync::mpsc::channel::<()>();
    std::thread::scope(|s| {
        // Shard 0/2 stops at its first progress report (registered, before
        // its first image) until the others have been tried.
        let first = s.spawn(move || {
            let mut e = engine(scene, settings.backend);
            let plan = two_by_two(scene);
            let mut observe = |f: f32| {
                if f == 0.0 {
                    paused.send(()).unwrap();
                    wait_go.recv().unwrap();
                }
                true
            };
            let shard = Shard { index: 0, count: 2 };
            bake::run_observed(
                scene,
                dir,
                settings,
                &bake::Sampling::FLAT,
                shard,
                e.as_mut(),
                |_| Ok(plan),
                &mut observe,
            )
        });
        wait_paused.recv().unwrap();
        // A temporary file while a shard runs may be that shard's own.
        let stray = dir.join("images").join(".v000-t000.exr.1-0.partial");
        std::fs::write(&stray, b"half").unwrap();
        let other = try_bake(settings, Shard { index: 1, count: 2 }).unwrap();
        assert_eq!(
            (other.rendered, other.removed, other.complete),
            (2, 0, false)
        );
        assert!(stray.exists());
        let more = Settings {
            spp: 3,
            ..*settings
        };
        for (settings, shard, needle) in [
            (settings, Shard::ALL, "in use"),
            (settings, Shard { index: 0, count: 2 }, "in use"),
            (settings, Shard { index: 2, count: 4 }, "in use"),
            (&more, Shard { index: 1, count: 2 }, "--spp 2, not 3"),
        ] {
            let err = format!("{:#}", try_bake(settings, shard).unwrap_err());
            assert!(
                err.contains(needle)
                    && err.contains("baking shard 0/2")
                    && (needle != "in use" || err.contains("--shard i/2")),
                "{shard:?}: {err}"
            );
        }
        go.send(()).unwrap();
        let first = first.join().unwrap().unwrap();
        assert_eq!((first.rendered, first.complete), (2, true));
        // Alone, a run knows nothing else writes the bake, and removes it.
        let again = try_bake(settings, Shard::ALL).unwrap();
        assert_eq!((again.rendered, again.removed), (0, 1));
        assert!(!stray.exists());
    });
}

/// The Cornell box's two-by-two plan baked whole and cropped, into
/// `dir/whole` and `dir/partial`, sampled to a noise target (whose floor
/// and windows of neighbours must come out the same cropped).
fn whole_and_partial(scene: &Scene, dir: &Path, size: u32) -> (bake::Bake, bake::Bake) {
    let sampling = bake::Sampling {
        noise: Some(0.1),
        max_spp: Some(6),
    };
    let open = |whole: bool, name: &str| {
        let mut settings = Settings {
            size,
            spp: 2,
            ..tiny(IndirectSource::Path)
        };
        settings.planning.whole = whole;
        let dir = dir.join(name);
        let mut e = engine(scene, settings.backend);
        let plan = two_by_two(scene);
        bake::run_observed(
            scene,
            &dir,
            &settings,
            &sampling,
            Shard::ALL,
            e.as_mut(),
            |_| Ok(plan),
            &mut |_| true,
        )
        .unwrap_or_else(|e| panic!("{e:#}"));
        bake::Bake::open(&dir, scene).unwrap_or_else(|e| panic!("{e:#}"))
    };
    (open(true, "whole"), open(false, "partial"))
}

#[test]
fn a_window_holds_every_pixel_that_sees_the_scene_as_the_whole_image_has_it() {
    let scene = load(&scene_path("cornell-box"));
    let tmp = tempfile::tempdir().unwrap();
    let size = 384;
    let (whole, partial) = whole_and_partial(&scene, tmp.path(), size);
    let (mut seen, mut kept) = (0u64, 0u64);
    for k in 0..whole.manifest.images.len() {
        let (w, _) = whole.read_layers(k, &[]).unwrap();
        let (p, _) = partial.read_layers(k, &[]).unwrap();
        assert_eq!((w.width, w.height), (size, size));
        assert_eq!(w.meta.camera.window, None);
        let window = partial.manifest.windows[partial.manifest.images[k].view];
        let (x0, y0) = p.meta.camera.origin();
        assert_eq!(
            (x0, y0, p.width, p.height),
            (window.x, window.y, window.width, window.height)
        );
        assert_eq!(p.meta.camera.full_size(), (size, size));
        assert!(!window.is_whole(size), "image {k}: nothing cropped");
        kept += window.pixels();
        // Every pixel that sees geometry, with two pixels round it for the
        // footprints and filters beside silhouettes, lies in the window.
        let margin = 2;
        for y in 0..size {
            for x in 0..size {
                let i = (y * size + x) as usize;
                if w.object_id[i] == NO_HIT {
                    continue;
                }
                seen += 1;
                let inside = |a: u32, lo: u32, n: u32| {
                    (a >= lo + margin || lo == 0) && (a + margin < lo + n || lo + n == size)
                };
                assert!(
                    inside(x, x0, p.width) && inside(y, y0, p.height),
                    "image {k}: pixel ({x}, {y}) sees object {} and lies outside (or within \
                     {margin} pixels of the edge of) the window {window}",
                    w.object_id[i]
                );
            }
        }
        // And the window's pixels are the whole image's, bit for bit.
        for y in 0..p.height {
            for x in 0..p.width {
                let (i, j) = (
                    ((y + y0) * size + x + x0) as usize,
                    (y * p.width + x) as usize,
                );
                assert_eq!(
                    (
                        w.radiance[i].to_array().map(f32::to_bits),
                        w.distance[i].to_bits(),
                        w.object_id[i],
                        w.primitive_id[i],
                        w.normal[i].to_array().map(f32::to_bits)
                    ),
                    (
                        p.radiance[j].to_array().map(f32::to_bits),
                        p.distance[j].to_bits(),
                        p.object_id[j],
                        p.primitive_id[j],
                        p.normal[j].to_array().map(f32::to_bits)
                    ),
                    "image {k}: window pixel ({x}, {y}), whole pixel ({}, {})",
                    x + x0,
                    y + y0
                );
            }
        }
    }
    let all = u64::from(size * size) * whole.manifest.images.len() as u64;
    eprintln!(
        "{:.1}% of the whole images' pixels see geometry; the windows keep {:.1}%",
        100.0 * seen as f64 / all as f64,
        100.0 * kept as f64 / all as f64
    );
    assert!(seen > 0);
}

/// `dir`'s manifest as JSON, changed by `change`, written back.
fn edit_manifest(dir: &Path, change: impl FnOnce(&mut serde_json::Value)) {
    let path = dir.join(bake::manifest::MANIFEST);
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    change(&mut m);
    std::fs::write(&path, serde_json::to_string_pretty(&m).unwrap()).unwrap();
}

#[test]
fn a_bad_window_in_a_manifest_or_an_exr_is_refused_naming_the_file_and_field() {
    let scene = load(&scene_path("cornell-box"));
    let tmp = tempfile::tempdir().unwrap();
    let settings = Settings {
        size: 384,
        spp: 1,
        ..tiny(IndirectSource::Path)
    };
    let good = tmp.path().join("good");
    bake_into(&scene, &good, &settings, Shard::ALL);
    let m = bake::Manifest::read(&good).unwrap();
    let window = m.windows[0];
    assert!(!window.is_whole(384) && window.x + window.width + 16 <= 384);
    let copy = |name: &str| {
        let dir = tmp.path().join(name);
        std::fs::create_dir_all(dir.join("images")).unwrap();
        for f in ["manifest.json".to_string()]
            .into_iter()
            .chain(m.images.iter().map(|e| e.file.clone()))
        {
            std::fs::copy(good.join(&f), dir.join(&f)).unwrap();
        }
        dir
    };
    let refused =
        |dir: &Path| -> String { format!("{:#}", bake::Bake::open(dir, &scene).unwrap_err()) };
    let has = |e: &str, needles: &[&str]| {
        for n in needles {
            assert!(e.contains(n), "`{n}` not in: {e}");
        }
    };

    // A window outside the image, or a missing one.
    let dir = copy("outside");
    edit_manifest(&dir, |m| m["windows"][1]["x"] = 300.into());
    has(
        &refused(&dir),
        &["manifest.json", "`windows[1]`", "outside the 384x384"],
    );
    let dir = copy("missing");
    edit_manifest(&dir, |m| m["windows"] = serde_json::json!([]));
    has(
        &refused(&dir),
        &[
            "manifest.json",
            "`windows` has 0 entries for the plan's 2 views",
        ],
    );
    // A window inside the image that is not the one its images hold: the
    // bake opens, its images do not.
    let dir = copy("moved");
    edit_manifest(&dir, |m| m["windows"][0]["x"] = (window.x + 16).into());
    let b = bake::Bake::open(&dir, &scene).unwrap();
    let e = format!("{:#}", b.read(0).unwrap_err());
    has(&e, &[&m.images[0].file, "data window", "`windows[0]`"]);
    // A manifest of a later version is refused as before.
    let dir = copy("later");
    edit_manifest(&dir, |m| m["version"] = 9.into());
    has(&refused(&dir), &["manifest.json", "`version` is 9"]);

    // An EXR whose data window does not lie in its display window, with
    // either reader.
    let file = good.join(&m.images[0].file);
    let mut exr = exr::prelude::read_all_data_from_file(&file).unwrap();
    exr.attributes.display_window =
        exr::prelude::IntegerBounds::new(exr::prelude::Vec2(0, 0), exr::prelude::Vec2(200, 200));
    let bad = tmp.path().join("bad.exr");
    exr::prelude::WritableImage::write(&exr)
        .to_file(&bad)
        .unwrap();
    let bad_name = bad.display().to_string();
    for e in [
        rangewalk::image::read_exr(&bad).unwrap_err(),
        rangewalk::image::exr_io::read(&bad).unwrap_err(),
    ] {
        has(
            &format!("{e:#}"),
            &[&bad_name, "`dataWindow`", "`displayWindow`"],
        );
    }
}

#[test]
fn a_bake_of_manifest_version_4_reads_as_whole_images() {
    let scene = load(&scene_path("cornell-box"));
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("bake");
    let mut settings = Settings {
        size: 256,
        spp: 1,
        ..tiny(IndirectSource::Path)
    };
    settings.planning.whole = true;
    bake_into(&scene, &dir, &settings, Shard::ALL);
    let before: Vec<_> = {
        let b = bake::Bake::open(&dir, &scene).unwrap();
        (0..b.manifest.images.len())
            .map(|k| b.read_layers(k, &[]).unwrap().0)
            .collect()
    };
    // What version 4 wrote: no windows, no `whole` in the settings.
    edit_manifest(&dir, |m| {
        m["version"] = 4.into();
        m.as_object_mut().unwrap().remove("windows");
        m["settings"]["planning"]
            .as_object_mut()
            .unwrap()
            .remove("whole");
    });
    let b = bake::Bake::open(&dir, &scene).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(b.manifest.windows.iter().all(|w| w.is_whole(256)));
    for (k, want) in before.iter().enumerate() {
        assert_eq!(&b.read_layers(k, &[]).unwrap().0, want, "image {k}");
    }
}

/// A bake of the Cornell box with windows (384²: the box covers the
/// middle third of the sphere's side, past the first 128-pixel block), and `dir`'s copy of it as version 5 wrote
/// it, without planes files, which is read from its EXRs.
fn bake_and_version_5_copy(scene: &Scene, dir: &Path) -> (bake::Bake, bake::Bake) {
    let settings = Settings {
        size: 384,
        spp: 1,
        ..tiny(IndirectSource::Path)
    };
    let new = dir.join("v6");
    bake_into(scene, &new, &settings, Shard::ALL);
    let old = dir.join("v5");
    std::fs::create_dir_all(old.join("images")).unwrap();
    let m = bake::Manifest::read(&new).unwrap();
    assert!(m.has_planes());
    std::fs::copy(new.join("manifest.json"), old.join("manifest.json")).unwrap();
    for e in &m.images {
        std::fs::copy(new.join(&e.file), old.join(&e.file)).unwrap();
    }
    edit_manifest(&old, |m| m["version"] = 5.into());
    let open = |d: &Path| bake::Bake::open(d, scene).unwrap_or_else(|e| panic!("{e:#}"));
    (open(&new), open(&old))
}

#[test]
fn planes_files_read_as_their_exrs_and_make_the_same_frames_bit_for_bit() {
    use rangewalk::image::planes_file;
    use rangewalk::image::planes_file::BasePlanes;
    use rangewalk::synth::{Options, Synthesizer, DEFAULT_BUDGET};
    let scene = load(&scene_path("cornell-box"));
    let tmp = tempfile::tempdir().unwrap();
    let (new, old) = bake_and_version_5_copy(&scene, tmp.path());
    assert!(!old.manifest.has_planes());
    assert!(new.manifest.has_base_planes());
    // A copy as version 7 wrote it: its planes files hold the range images
    // whole (planes file version 2).
    let v7 = tmp.path().join("v7");
    std::fs::create_dir_all(v7.join("images")).unwrap();
    std::fs::copy(new.dir.join("manifest.json"), v7.join("manifest.json")).unwrap();
    for (k, e) in new.manifest.images.iter().enumerate() {
        let planes = new.dir.join(format!("{}.planes", e.file));
        assert!(planes.exists(), "{} has no planes file", e.file);
        assert!(!old.dir.join(format!("{}.planes", e.file)).exists());
        let sum = e.fnv1a64.clone().unwrap();
        let file = planes_file::PlanesFile::open(&planes, &sum).unwrap();
        assert_eq!(file.version(), 3, "image {k}");
        let exr = new.read_layers(k, &[]).unwrap().0;
        assert!(exr.meta.camera.window.is_some(), "image {k} is not cropped");
        assert_eq!(
            new.read_base(k).unwrap(),
            BasePlanes::of(exr.clone()),
            "image {k}"
        );
        assert_eq!(new.read_range(k).unwrap(), exr, "image {k}");
        assert_eq!(old.read_range(k).unwrap(), exr, "image {k}");
        std::fs::copy(new.dir.join(&e.file), v7.join(&e.file)).unwrap();
        let v2 = bake::manifest::planes_path(&v7.join(&e.file));
        planes_file::write(&v2, &exr, &sum).unwrap();
    }
    edit_manifest(&v7, |m| m["version"] = 7.into());
    let v7 = bake::Bake::open(&v7, &scene).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(v7.manifest.has_planes() && !v7.manifest.has_base_planes());
    for k in 0..v7.manifest.images.len() {
        assert_eq!(v7.read_range(k).unwrap(), old.read_range(k).unwrap());
        let e = format!("{:#}", v7.read_base(k).unwrap_err());
        assert!(e.contains("range images, not bases"), "{e}");
    }
    let mut seven = Synthesizer::new(&scene, &v7, DEFAULT_BUDGET);
    let main = scene.camera("main").unwrap();
    let p = Projection::Perspective {
        vfov_deg: main.vfov_deg,
    };
    let Some(rangewalk::scene::ViewSpace::Segment { a, b }) = scene.view_space else {
        panic!("the Cornell box's view space is a segment");
    };
    let (mut lazy, mut eager) = (
        Synthesizer::new(&scene, &new, DEFAULT_BUDGET),
        Synthesizer::new(&scene, &old, DEFAULT_BUDGET),
    );
    for (s, t) in [(0.0, 0.0), (0.4, 0.5), (1.0, 0.8)] {
        let camera = Camera::looking(a.lerp(b, s), main.direction, main.up, p, 40, 40).unwrap();
        let (mut f, _) = lazy.frame(&camera, t, &Options::default()).unwrap();
        let (g, _) = eager.frame(&camera, t, &Options::default()).unwrap();
        let (mut h, _) = seven.frame(&camera, t, &Options::default()).unwrap();
        h.meta.scene = g.meta.scene.clone();
        assert!(
            h == g,
            "frame at s = {s}, t = {t} from version-2 planes files differs"
        );
        // The provenance names the bake's folder; every pixel must agree.
        assert!(f.meta.scene.contains("v6") && g.meta.scene.contains("v5"));
        f.meta.scene = g.meta.scene.clone();
        assert!(f == g, "frame at s = {s}, t = {t} differs");
        assert!(
            f.object_id.iter().any(|&o| o != NO_HIT),
            "frame sees nothing"
        );
    }
}

#[test]
fn a_damaged_missing_or_foreign_planes_file_is_named_when_read_and_rendered_again() {
    let scene = load(&scene_path("cornell-box"));
    let tmp = tempfile::tempdir().unwrap();
    let (new, _) = bake_and_version_5_copy(&scene, tmp.path());
    let dir = new.dir.clone();
    let m = new.manifest.clone();
    let planes = |k: usize| dir.join(format!("{}.planes", m.images[k].file));
    let before: Vec<Vec<u8>> = (0..4).map(|k| std::fs::read(planes(k)).unwrap()).collect();
    let error = |k: usize| format!("{:#}", new.read_base(k).unwrap_err());
    let has = |e: &str, needles: &[&str]| {
        for n in needles {
            assert!(e.contains(n), "`{n}` not in: {e}");
        }
    };
    let name = |k: usize| planes(k).display().to_string();

    // A flipped bit in the last pixel's normal: the last chunk of the
    // last plane.
    let mut bytes = before[0].clone();
    *bytes.last_mut().unwrap() ^= 1;
    std::fs::write(planes(0), &bytes).unwrap();
    let w = m.windows[m.images[0].view];
    let last = (w.width as usize * w.height as usize - 1) / rangewalk::image::planes_file::CHUNK;
    has(
        &error(0),
        &[
            &name(0),
            &format!("chunk {last} of plane `normal`"),
            "damaged",
            "run the bake again",
        ],
    );
    // A changed header (the camera's first word).
    let mut bytes = before[1].clone();
    let at = bytes
        .windows(10)
        .position(|w| w == b"\"position\"")
        .expect("the header holds the camera");
    bytes[at + 13] ^= 1;
    std::fs::write(planes(1), &bytes).unwrap();
    has(&error(1), &[&name(1), "header is damaged"]);
    // Another image's planes, whole and undamaged.
    std::fs::write(planes(2), &before[3]).unwrap();
    has(&error(2), &[&name(2), "another image"]);
    // None at all, and one cut short.
    std::fs::remove_file(planes(3)).unwrap();
    has(&error(3), &[&name(3), "run the bake again"]);
    let s = bake::status::status(&dir).unwrap();
    assert_eq!(s.missing, vec![m.images[3].file.clone()], "{s:?}");

    // The bake renders those four again and nothing else, and the files
    // come back as they were.
    let settings = new.manifest.settings;
    let s = bake_into(&scene, &dir, &settings, Shard::ALL);
    assert_eq!((s.rendered, s.reused, s.complete), (4, 0, true), "{s:?}");
    for (k, want) in before.iter().enumerate() {
        assert!(&std::fs::read(planes(k)).unwrap() == want, "image {k}");
    }
    std::fs::write(planes(1), &before[1][..before[1].len() - 7]).unwrap();
    has(&error(1), &[&name(1), "cut short"]);
}

#[test]
fn a_version_5_bake_resumed_renders_what_it_lacks_without_planes_files() {
    let scene = load(&scene_path("cornell-box"));
    let tmp = tempfile::tempdir().unwrap();
    let (new, old) = bake_and_version_5_copy(&scene, tmp.path());
    let lost = old.dir.join(&old.manifest.images[1].file);
    std::fs::remove_file(&lost).unwrap();
    let s = bake_into(&scene, &old.dir, &new.manifest.settings, Shard::ALL);
    assert_eq!((s.rendered, s.reused, s.complete), (1, 3, true), "{s:?}");
    assert!(lost.exists());
    assert!(!bake::manifest::planes_path(&lost).exists());
    let m = bake::Manifest::read(&old.dir).unwrap();
    assert_eq!(m.version, 5);
    let b = bake::Bake::open(&old.dir, &scene).unwrap();
    assert_eq!(b.read_range(1).unwrap(), new.read_range(1).unwrap());
}
