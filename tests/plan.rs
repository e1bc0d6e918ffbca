//! Planning (paper §4.1-4.2): id-images, fitness, base views and time lists.
//! Resolutions are small so that every test stays fast, the studio's 72k
//! triangles included.

use std::path::Path;

use glam::Vec3;
use rangewalk::accel::{Backend, InstancedEngine};
use rangewalk::camera::{Camera, Projection};
#[cfg(feature = "embree")]
use rangewalk::image::NO_HIT;
use rangewalk::plan::coverage::coverage;
#[cfg(feature = "embree")]
use rangewalk::plan::lights;
use rangewalk::plan::{self, fitness, idimage, views, IdView, Plan, PlanOptions, ViewFitness};
use rangewalk::quality::Quality;
use rangewalk::ray::Ray;
use rangewalk::scene::{Scene, ViewSpace};

mod common;
use common::{engine, load, rangewalk, scenes_dir};

fn bundled() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(scenes_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("scene.toml").exists())
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert!(names.len() >= 5, "bundled scenes: {names:?}");
    names
}

fn backends() -> &'static [Backend] {
    let b = Backend::available();
    assert!(!b.is_empty(), "this build has no ray engine");
    b
}

fn plan_with(s: &Scene, q: f32, resolution: Option<u32>, master_list: bool) -> Plan {
    let mut e = engine(s, Backend::default_available());
    plan::make(
        s,
        e.as_mut(),
        &PlanOptions {
            quality: Quality::new(q).unwrap(),
            resolution,
            master_list,
            view_fitness: ViewFitness::Ids,
        },
    )
    .unwrap_or_else(|err| panic!("{}: {err:#}", s.source.display()))
}

fn sphere_image(e: &dyn InstancedEngine, at: Vec3, size: u32) -> idimage::IdImage {
    idimage::render(e, &IdView::Camera(views::sphere(at, size).unwrap()))
}

/// Both engines see the same object at (nearly) every pixel, through every
/// kind of id-image camera planning uses, on every bundled scene.
///
/// The bound: a pixel's ray can graze a silhouette or a shared triangle
/// edge within a rounding error, where the two engines' different
/// intersection arithmetic may pick different sides; such rays are a
/// vanishing fraction of the pixels, so 1 in 1000 leaves room for a few of
/// them on these ~430k pixels without hiding a real disagreement (a wrong
/// transform or id mapping changes whole regions). Compiled only where
/// both engines exist (not in the pure-Rust build, which has one).
#[cfg(feature = "embree")]
#[test]
fn engines_give_the_same_ids() {
    let all = [Backend::Bvh, Backend::Embree];
    let mut compared = 0usize;
    let mut differ = 0usize;
    for name in bundled() {
        let s = load(&name);
        let t = 0.5 * (s.animation.start + s.animation.end);
        let cam = s.camera("main").unwrap();
        let mut cams: Vec<IdView> = [
            cam.perspective(96, 80).unwrap(),
            cam.with_projection(Projection::Fisheye, 96, 96).unwrap(),
            views::sphere(cam.position, 96).unwrap(),
        ]
        .into_iter()
        .map(IdView::Camera)
        .collect();
        let bounds = s.bounds(t);
        for probe in lights::probes(&s, bounds) {
            cams.push(probe.view(&s, t, 96).unwrap());
        }
        let images: Vec<Vec<idimage::IdImage>> = all
            .iter()
            .map(|&b| {
                let mut e = engine(&s, b);
                e.set_transforms(&s.at(t)).unwrap();
                cams.iter()
                    .map(|c| idimage::render(e.as_ref(), c))
                    .collect()
            })
            .collect();
        for other in &images[1..] {
            for (a, b) in images[0].iter().zip(other) {
                assert_eq!(a.outside, b.outside);
                compared += a.ids.len();
                let d = a.ids.iter().zip(&b.ids).filter(|(x, y)| x != y).count();
                differ += d;
            }
        }
        // The scene's own camera sees something: a wrong camera would
        // compare empty images and agree trivially. (Light cameras may
        // rightly see nothing: the furnace's look out of its closed cube.)
        for im in &images[0][..3] {
            assert!(
                im.ids.iter().any(|&id| id != NO_HIT),
                "{name}: an id-image saw nothing"
            );
        }
    }
    eprintln!("{differ} of {compared} pixels differ between the engines");
    assert!(compared > 100_000, "{compared} pixels compared");
    assert!(
        differ as f64 <= 1e-3 * compared as f64,
        "{differ} of {compared} pixels differ"
    );
}

#[test]
fn identical_cameras_have_fitness_one() {
    let s = load("cornell-box");
    for &b in backends() {
        let e = engine(&s, b);
        let at = Vec3::new(278.0, 273.0, 280.0);
        let a = sphere_image(e.as_ref(), at, 32);
        let c = sphere_image(e.as_ref(), at, 32);
        assert_eq!(fitness(&[&a, &c]), 1.0, "{b}");
        let other = sphere_image(e.as_ref(), Vec3::new(100.0, 100.0, 100.0), 32);
        assert!(fitness(&[&a, &other]) < 1.0, "{b}");
    }
}

/// Two cameras inside the Cornell box (above both boxes, so that neither
/// ends up inside one), moved apart step by step: what they see agrees less
/// and less.
#[test]
fn fitness_falls_as_cameras_move_apart() {
    let s = load("cornell-box");
    let e = engine(&s, Backend::default_available());
    let centre = Vec3::new(278.0, 450.0, 280.0);
    let f: Vec<f32> = [0.0f32, 10.0, 20.0, 40.0, 80.0, 160.0, 240.0]
        .iter()
        .map(|&d| {
            let a = sphere_image(e.as_ref(), centre - Vec3::X * d * 0.5, 64);
            let b = sphere_image(e.as_ref(), centre + Vec3::X * d * 0.5, 64);
            fitness(&[&a, &b])
        })
        .collect();
    assert_eq!(f[0], 1.0, "{f:?}");
    for w in f.windows(2) {
        // Monotone up to a little pixel noise.
        assert!(w[1] <= w[0] + 0.01, "{f:?}");
    }
    // Measured 0.97 at 10 mm, 0.57 at 240 mm.
    assert!(f[f.len() - 1] < f[1] - 0.2, "{f:?}");
}

#[test]
fn inside_and_outside_a_closed_box_disagree() {
    let s = load("furnace");
    for &b in backends() {
        let e = engine(&s, b);
        let inside = sphere_image(e.as_ref(), Vec3::splat(0.5), 64);
        let outside = sphere_image(e.as_ref(), Vec3::new(3.0, 0.5, 0.5), 64);
        assert!(inside.ids.iter().all(|&id| id == 0), "{b}: inside sees out");
        let f = fitness(&[&inside, &outside]);
        assert!(f < 0.1, "{b}: fitness {f}");
    }
}

/// The surfaces every corner sees, counted independently of
/// `coverage`'s shadow rays: each corner traces its own ray towards the
/// centre's hit point and must first meet a surface there, from the side
/// the centre sees.
fn seen_by_every_corner(e: &dyn InstancedEngine, centre: &Camera, corners: &[Vec3]) -> f32 {
    let (w, h) = (centre.width, centre.height);
    let mut seen = 0usize;
    for j in 0..h {
        for i in 0..w {
            let ray = centre.ray(i as f32 + 0.5, j as f32 + 0.5).unwrap();
            let Some(hit) = e.intersect(&ray) else {
                seen += 1;
                continue;
            };
            let p = ray.at(hit.t);
            let side = (centre.position - p).dot(hit.normal);
            let every = corners.iter().all(|&c| {
                let to = Ray::new(c, (p - c).normalize());
                e.intersect(&to).is_some_and(|back| {
                    (back.t - (p - c).length()).abs() <= 1e-3 * (p - c).length()
                        && (c - p).dot(back.normal) * side > 0.0
                })
            });
            seen += usize::from(every);
        }
    }
    seen as f32 / (w * h) as f32
}

/// Coverage against that count inside the Cornell box, with corners above
/// the boxes around a centre: the tall box hides part of the floor from
/// some corners. The two counts differ only for surface points within
/// rounding of a silhouette in some corner's line of sight: 1 in 500 of
/// the pixels at most.
#[test]
fn coverage_counts_the_surfaces_every_corner_sees() {
    let s = load("cornell-box");
    let at = Vec3::new(278.0, 420.0, 250.0);
    let centre = views::sphere(at, 96).unwrap();
    let mut corners = Vec::new();
    for dx in [-150.0, 150.0] {
        for dy in [-50.0, 50.0] {
            for dz in [-150.0, 150.0] {
                corners.push(at + Vec3::new(dx, dy, dz));
            }
        }
    }
    for &b in backends() {
        let e = engine(&s, b);
        let c = coverage(e.as_ref(), &centre, &corners);
        let want = seen_by_every_corner(e.as_ref(), &centre, &corners);
        eprintln!("{b}: coverage {c}, counted {want}");
        assert!(
            (c - want).abs() <= 2e-3,
            "{b}: coverage {c}, counted {want}"
        );
        assert!(
            c > 0.3 && c < 0.99,
            "{b}: coverage {c}: the occluders should matter"
        );
        // Seen from the centre itself, every surface is seen.
        let own = coverage(e.as_ref(), &centre, &[at]);
        assert!(
            own >= 0.998,
            "{b}: the centre sees {own} of its own surfaces"
        );
    }
}

/// A box view space around the Cornell box's tall box: corners on either
/// side of it do not see the same surfaces, so the coverage fitness splits
/// cells, and every cell it keeps reached the quality.
#[test]
fn coverage_fitness_splits_around_an_occluder() {
    let mut s = load("cornell-box");
    s.view_space = Some(ViewSpace::Box {
        min: Vec3::new(150.0, 100.0, 150.0),
        max: Vec3::new(500.0, 500.0, 500.0),
    });
    let mut e = engine(&s, Backend::default_available());
    let p = plan::make(
        &s,
        e.as_mut(),
        &PlanOptions {
            quality: Quality::new(0.9).unwrap(),
            resolution: Some(32),
            master_list: false,
            view_fitness: ViewFitness::Coverage,
        },
    )
    .unwrap();
    assert_eq!(p.view_fitness, ViewFitness::Coverage);
    assert!(p.cells.iter().any(|c| c.split), "{:?}", p.cells);
    for c in &p.cells {
        if let (Some(f), false) = (c.fitness, c.split) {
            assert!(f >= 0.9, "{c:?}");
        }
    }
    let again: Plan = serde_json::from_str(&serde_json::to_string(&p).unwrap()).unwrap();
    assert_eq!(again.view_fitness, ViewFitness::Coverage);
}

fn corners(space: &ViewSpace) -> Vec<Vec3> {
    match *space {
        ViewSpace::Segment { a, b } => vec![a, b],
        ViewSpace::Rectangle { min, max } | ViewSpace::Box { min, max } => {
            let mut out: Vec<Vec3> = (0..8)
                .map(|c| {
                    Vec3::new(
                        if c & 1 == 0 { min.x } else { max.x },
                        if c & 2 == 0 { min.y } else { max.y },
                        if c & 4 == 0 { min.z } else { max.z },
                    )
                })
                .collect();
            out.sort_by(|a, b| a.to_array().partial_cmp(&b.to_array()).unwrap());
            out.dedup();
            out
        }
    }
}

fn sorted(mut v: Vec<Vec3>) -> Vec<Vec3> {
    v.sort_by(|a, b| a.to_array().partial_cmp(&b.to_array()).unwrap());
    v
}

#[test]
fn quality_zero_gives_the_corners() {
    let mut cases: Vec<Scene> = ["cornell-box", "glossy-sun"].map(load).into();
    let mut boxed = load("cornell-box");
    boxed.view_space = Some(ViewSpace::Box {
        min: Vec3::new(100.0, 100.0, -500.0),
        max: Vec3::new(400.0, 450.0, 200.0),
    });
    cases.push(boxed);
    let mut dims = Vec::new();
    for s in cases {
        let space = s.view_space.unwrap();
        dims.push(space.dimensions());
        let p = plan_with(&s, 0.0, Some(16), false);
        let got = sorted(p.views.iter().map(|v| v.position).collect());
        let want = sorted(corners(&space));
        assert_eq!(got.len(), 1 << space.dimensions());
        for (g, w) in got.iter().zip(&want) {
            assert!(
                (*g - *w).length() < 1e-3 * w.length().max(1.0),
                "{g} vs {w}"
            );
        }
        assert_eq!(p.cells.len(), 1);
        assert_eq!(p.cells[0].fitness, None);
    }
    assert_eq!(dims, [1, 2, 3]);
}

/// The number of views and of (view, time) images never drops as the
/// quality rises, and shared corners are one view, on every bundled scene
/// (at one fixed resolution, so that the fitness values are the same).
#[test]
fn higher_quality_never_gives_fewer_views_or_times() {
    for name in bundled() {
        let s = load(&name);
        let mut last = (0usize, 0usize, 0usize);
        for q in [0.0, 0.3, 0.6, 0.9, 1.0] {
            let p = plan_with(&s, q, Some(16), false);
            let positions: Vec<[u32; 3]> = p
                .views
                .iter()
                .map(|v| v.position.to_array().map(f32::to_bits))
                .collect();
            let mut unique = positions.clone();
            unique.sort();
            unique.dedup();
            assert_eq!(
                unique.len(),
                positions.len(),
                "{name} q={q}: duplicate views"
            );
            for v in &p.views {
                assert!(!v.times.is_empty());
                assert!(
                    v.times.windows(2).all(|w| w[0] < w[1]),
                    "{name}: {:?}",
                    v.times
                );
            }
            let now = (
                p.views.len(),
                p.views.iter().map(|v| v.times.len()).sum(),
                p.light_times.len(),
            );
            assert!(
                now.0 >= last.0 && now.1 >= last.1 && now.2 >= last.2,
                "{name}: q={q} gives (views, images, light times) {now:?} after {last:?}"
            );
            last = now;
        }
        if name == "cornell-box" {
            assert!(last.0 > 2 && last.2 > 2, "{name} at q = 1: {last:?}");
        }
    }
}

#[test]
fn static_scene_gets_one_time() {
    for name in ["studio", "furnace"] {
        let s = load(name);
        assert!(s.is_static());
        let p = plan_with(&s, 0.9, Some(16), false);
        assert_eq!(p.light_times, [s.animation.start], "{name}");
        for v in &p.views {
            assert_eq!(v.times, [s.animation.start], "{name}");
        }
        assert!(p.intervals.is_empty(), "{name}");
        assert!(
            p.skipped.iter().any(|w| w.contains("static scene")),
            "{name}: {:?}",
            p.skipped
        );
    }
    // The furnace has no view space: one view at its camera, said so.
    let s = load("furnace");
    let p = plan_with(&s, 0.9, Some(16), false);
    assert_eq!(p.views.len(), 1);
    assert_eq!(p.views[0].position, s.cameras[0].position);
    assert!(p.skipped.iter().any(|w| w.contains("no view space")));
}

const CUBE: &str = "v 0 0 0\nv 0 0 1\nv 0 1 0\nv 0 1 1\nv 1 0 0\nv 1 0 1\nv 1 1 0\nv 1 1 1\n\
f 1 2 4 3\nf 5 7 8 6\nf 1 5 6 2\nf 3 4 8 7\nf 1 3 7 5\nf 2 6 8 4\n";

/// The Cornell box (its boxes moving or not) with a closed container on
/// the floor; inside it, a small cube that moves or not.
fn container_scene(dir: &Path, boxes_move: bool, hidden_moves: bool) -> Scene {
    std::fs::copy(
        scenes_dir().join("cornell-box/cornell-box.obj"),
        dir.join("cornell-box.obj"),
    )
    .unwrap();
    std::fs::write(dir.join("cube.obj"), CUBE).unwrap();
    let mut toml = String::from(
        "[animation]\nstart = 0\nend = 1\nfps = 30\n\n\
         [[materials]]\nname = \"white\"\ntype = \"diffuse\"\nreflectance = [0.7, 0.7, 0.7]\n\n\
         [[materials]]\nname = \"light\"\ntype = \"diffuse\"\nreflectance = [0.7, 0.7, 0.7]\nemission = [17, 12, 4]\n\n",
    );
    for g in [
        "floor",
        "ceiling",
        "back",
        "green-wall",
        "red-wall",
        "light",
        "short-box",
        "tall-box",
    ] {
        let m = if g == "light" { "light" } else { "white" };
        toml += &format!(
            "[[objects]]\nname = \"{g}\"\nmesh = \"cornell-box.obj\"\ngroup = \"{g}\"\nmaterial = \"{m}\"\n"
        );
        if g == "short-box" && boxes_move {
            toml += "[[objects.keyframes]]\ntime = 0\n[[objects.keyframes]]\ntime = 1\ntranslate = [100, 0, -50]\n";
        }
        toml += "\n";
    }
    // A 100 mm box at the back left corner, and a 20 mm cube inside it
    // sliding from one side to the other.
    toml += "[[objects]]\nname = \"container\"\nmesh = \"cube.obj\"\nmaterial = \"white\"\n\
             [[objects.keyframes]]\ntime = 0\ntranslate = [30, 0, 430]\nscale = 100\n\n\
             [[objects]]\nname = \"hidden\"\nmesh = \"cube.obj\"\nmaterial = \"white\"\n\
             [[objects.keyframes]]\ntime = 0\ntranslate = [40, 10, 440]\nscale = 20\n";
    if hidden_moves {
        toml += "[[objects.keyframes]]\ntime = 1\ntranslate = [100, 60, 500]\nscale = 20\n";
    }
    toml += "\n[[cameras]]\nname = \"main\"\nposition = [278, 273, -800]\nlook_at = [278, 273, 0]\nvfov = 39.3\n\n\
             [view_space]\ntype = \"segment\"\na = [78, 273, -800]\nb = [478, 273, -800]\n";
    let path = dir.join("scene.toml");
    std::fs::write(&path, toml).unwrap();
    Scene::load(path).unwrap()
}

#[test]
fn a_hidden_moving_object_adds_no_time() {
    let dir = tempfile::tempdir().unwrap();
    let times = |p: &Plan| -> Vec<(Vec3, Vec<f32>)> {
        p.views
            .iter()
            .map(|v| (v.position, v.times.clone()))
            .collect()
    };
    // With the Cornell box's short box moving: the same plan with or
    // without the hidden motion.
    let still = container_scene(dir.path(), true, false);
    let hidden = container_scene(dir.path(), true, true);
    assert!(!hidden.objects.last().unwrap().motion.is_static());
    let (a, b) = (
        plan_with(&still, 0.9, Some(32), false),
        plan_with(&hidden, 0.9, Some(32), false),
    );
    assert_eq!(times(&a), times(&b));
    assert_eq!(a.light_times, b.light_times);
    assert!(
        a.light_times.len() > 1,
        "the moving short box needs times: {:?}",
        a.light_times
    );
    // With nothing else moving: one time everywhere, and the reasons.
    let only = container_scene(dir.path(), false, true);
    assert!(!only.is_static());
    let p = plan_with(&only, 0.9, Some(32), false);
    assert_eq!(p.light_times, [0.0]);
    for v in &p.views {
        assert_eq!(v.times, [0.0]);
    }
    assert!(
        p.skipped.iter().any(|w| w.contains("adds no times")),
        "{:?}",
        p.skipped
    );
    assert!(
        p.skipped.iter().any(|w| w.contains("keeps the light list")),
        "{:?}",
        p.skipped
    );
}

/// The same scene with the hidden cube sliding out of its container into
/// view does get more times: the test above can fail.
#[test]
fn a_visible_moving_object_adds_times() {
    let dir = tempfile::tempdir().unwrap();
    let s = container_scene(dir.path(), false, true);
    let mut s2 = s.clone();
    let last = s2.objects.len() - 1;
    let keys = s.objects[last].motion.keys().to_vec();
    let mut moved = keys.clone();
    moved[1].translation = Vec3::new(300.0, 10.0, 200.0);
    s2.objects[last].motion = rangewalk::scene::Motion::new(moved);
    let p = plan_with(&s2, 0.9, Some(32), false);
    assert!(p.light_times.len() > 1, "{:?}", p.light_times);
    assert!(p.views.iter().all(|v| v.times.len() > 1));
}

#[test]
fn master_list_is_the_union_for_every_view() {
    let s = load("glossy-sun");
    let own = plan_with(&s, 0.9, Some(24), false);
    let master = plan_with(&s, 0.9, Some(24), true);
    let mut union: Vec<f32> = own.views.iter().flat_map(|v| v.times.clone()).collect();
    union.sort_by(f32::total_cmp);
    union.dedup();
    assert_eq!(own.views.len(), master.views.len());
    for v in &master.views {
        assert_eq!(v.times, union);
    }
    for t in &own.light_times {
        assert!(own.views.iter().all(|v| v.times.contains(t)));
    }
}

#[test]
fn plan_json_round_trips_and_names_its_fields() {
    let s = load("cornell-box");
    let p = plan_with(&s, 0.6, Some(16), false);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plan.json");
    p.save(&path).unwrap();
    assert_eq!(Plan::load(&path).unwrap(), p);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    assert_eq!(v["views"][0]["position"].as_array().unwrap().len(), 3);
    assert!(v["views"][0]["times"].is_array());
    assert!(v["light_times"].is_array());
    assert_eq!(v["quality"].as_f64().unwrap() as f32, 0.6);
    assert!(v["steps"][0]["seconds"].is_number());
    // Only the plan is left in the folder: the temporary file was renamed.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn cli_writes_the_plan_and_names_bad_values() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plan.json");
    let scene = scenes_dir().join("cornell-box/scene.toml");
    let scene = scene.to_str().unwrap();
    let plan_to_out = |extra: &[&str]| {
        let mut args = vec![
            "plan",
            scene,
            "--quality",
            "0.6",
            "--resolution",
            "16",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        rangewalk(&args)
    };
    let r = plan_to_out(&["--view-segment", "-100,273,-800:500,273,-800"]);
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(
        r.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&r.stderr)
    );
    assert!(
        stdout.contains("base views") && stdout.contains("step "),
        "{stdout}"
    );
    let p = Plan::load(&out).unwrap();
    assert_eq!(p.views[0].position, Vec3::new(-100.0, 273.0, -800.0));
    assert_eq!(p.resolution, 16);
    assert_eq!(p.view_fitness, ViewFitness::Ids);
    let r = plan_to_out(&["--view-fitness", "coverage"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(
        Plan::load(&out).unwrap().view_fitness,
        ViewFitness::Coverage
    );

    for (args, names) in [
        (vec!["--quality", "1.5"], "--quality"),
        (
            vec!["--quality", "0.5", "--resolution", "2"],
            "--resolution 2",
        ),
        (
            vec!["--quality", "0.5", "--view-segment", "1,2:3,4,5"],
            "1,2",
        ),
        (
            vec!["--quality", "0.5", "--view-fitness", "pixels"],
            "--view-fitness",
        ),
    ] {
        let mut all = vec!["plan", scene];
        all.extend(args);
        let r = rangewalk(&all);
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success());
        assert!(stderr.contains(names), "{stderr}");
    }
    let r = rangewalk(&["plan", "no/such/scene.toml", "--quality", "0.5"]);
    assert!(String::from_utf8_lossy(&r.stderr).contains("no/such/scene.toml"));
}

/// A camera looking along a fixed direction sees the same thing wherever
/// the fisheye's uncovered corners are: they count for nothing.
#[test]
fn fisheye_corners_do_not_count() {
    let s = load("cornell-box");
    let e = engine(&s, Backend::default_available());
    let c = Camera::looking(
        Vec3::new(278.0, 273.0, -800.0),
        Vec3::Z,
        Vec3::Y,
        Projection::Fisheye,
        32,
        32,
    )
    .unwrap();
    let im = idimage::render(e.as_ref(), &IdView::Camera(c));
    // The pixels outside the image circle: about 1 - π/4 of them.
    let frac = im.outside as f32 / im.ids.len() as f32;
    assert!(
        (frac - (1.0 - std::f32::consts::FRAC_PI_4)).abs() < 0.03,
        "{frac}"
    );
    assert_eq!(fitness(&[&im, &im.clone()]), 1.0);
}

/// A box view space (3D) splits in eight: shared corners stay one view and
/// every view lies in the box.
#[test]
fn box_view_space_subdivides_in_3d() {
    let mut s = load("cornell-box");
    let (min, max) = (
        Vec3::new(100.0, 100.0, 100.0),
        Vec3::new(450.0, 500.0, 500.0),
    );
    s.view_space = Some(ViewSpace::Box { min, max });
    let p = plan_with(&s, 0.9, Some(16), false);
    assert!(p.views.len() > 8, "{} views", p.views.len());
    assert!(p.cells.iter().any(|c| c.split && c.corners.len() == 8));
    let mut keys: Vec<[u32; 3]> = p
        .views
        .iter()
        .map(|v| v.position.to_array().map(f32::to_bits))
        .collect();
    keys.sort();
    keys.dedup();
    assert_eq!(keys.len(), p.views.len());
    for v in &p.views {
        assert!(
            v.position.cmpge(min).all() && v.position.cmple(max).all(),
            "{}",
            v.position
        );
    }
}

/// The Cornell box scaled by 1e-4 and 1e4 plans the same views (scaled)
/// and the same times: nothing in planning depends on the scene's units.
#[test]
fn plans_do_not_depend_on_scale() {
    let base = plan_with(&load("cornell-box"), 0.98, Some(32), false);
    assert!(base.views.len() > 2 && base.light_times.len() > 2);
    for (name, scale) in [("cornell-box-1e-4", 1e-4f32), ("cornell-box-1e4", 1e4)] {
        let p = plan_with(&load(name), 0.98, Some(32), false);
        assert_eq!(p.views.len(), base.views.len(), "{name}");
        assert_eq!(p.light_times, base.light_times, "{name}");
        for (v, b) in p.views.iter().zip(&base.views) {
            assert_eq!(v.times, b.times, "{name}");
            let want = b.position * scale;
            assert!(
                (v.position - want).length() <= 1e-5 * want.length(),
                "{name}: {} vs {want}",
                v.position
            );
        }
    }
}
