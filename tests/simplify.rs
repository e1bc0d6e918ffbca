//! Geometric simplification (paper §4.3): pruning by visibility and size,
//! coarsening, bisection, and the studio's patch counts.

use std::fmt::Write as _;
use std::path::Path;

use glam::Vec3;
use rangewalk::accel::{self, Backend};
use rangewalk::quality::Quality;
use rangewalk::radiosity::simplify::{simplify_report, Fate, Report, AREA_TOLERANCE};
use rangewalk::radiosity::{simplify, Simplified};
use rangewalk::scene::Scene;

/// OBJ text accumulated group by group.
#[derive(Default)]
struct Obj {
    text: String,
    verts: usize,
}

impl Obj {
    fn group(&mut self, name: &str) {
        writeln!(self.text, "o {name}").unwrap();
    }

    fn quad(&mut self, p: [Vec3; 4]) {
        for v in p {
            writeln!(self.text, "v {} {} {}", v.x, v.y, v.z).unwrap();
        }
        let n = self.verts;
        writeln!(self.text, "f {} {} {}", n + 1, n + 2, n + 3).unwrap();
        writeln!(self.text, "f {} {} {}", n + 1, n + 3, n + 4).unwrap();
        self.verts += 4;
    }

    /// An axis-aligned box; `inward` turns its faces to the inside (a room).
    fn cube(&mut self, lo: Vec3, hi: Vec3, inward: bool) {
        let c = |i: usize| {
            Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        };
        // Outward windings of the six faces.
        let faces = [
            [0, 4, 6, 2],
            [1, 3, 7, 5],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 2, 3, 1],
            [4, 5, 7, 6],
        ];
        for f in faces {
            let mut q = f.map(c);
            if inward {
                q.reverse();
            }
            self.quad(q);
        }
    }

    /// A UV sphere of `seg` x `stacks` quads (two triangles each, the poles'
    /// degenerate halves are dropped by the loader).
    fn sphere(&mut self, c: Vec3, r: f32, seg: usize, stacks: usize) {
        let p = |i: usize, j: usize| {
            let th = std::f32::consts::PI * j as f32 / stacks as f32;
            let ph = std::f32::consts::TAU * i as f32 / seg as f32;
            c + r * Vec3::new(th.sin() * ph.cos(), -th.cos(), th.sin() * ph.sin())
        };
        for i in 0..seg {
            for j in 0..stacks {
                self.quad([p(i, j), p(i, j + 1), p(i + 1, j + 1), p(i + 1, j)]);
            }
        }
    }
}

/// A closed 4 m room seen from a rectangle at eye height, holding a crate,
/// a closed safe with a box inside, a finely tessellated ball and a board
/// with ten pebbles far smaller than any patch; outside
/// it a box and a lamp that no viewpoint can see.
fn rooms(dir: &Path) -> Scene {
    let mut o = Obj::default();
    o.group("room");
    o.cube(Vec3::ZERO, Vec3::splat(4.0), true);
    o.group("crate");
    o.cube(Vec3::new(1.0, 0.0, 1.0), Vec3::new(2.0, 1.0, 2.0), false);
    o.group("safe");
    o.cube(Vec3::new(2.5, 0.0, 2.5), Vec3::new(3.5, 1.0, 3.5), false);
    o.group("hidden");
    o.cube(Vec3::new(2.8, 0.2, 2.8), Vec3::new(3.2, 0.6, 3.2), false);
    o.group("ball");
    o.sphere(Vec3::new(1.5, 2.5, 3.0), 0.5, 48, 24);
    o.group("pebbles");
    o.cube(Vec3::new(0.2, 0.0, 2.5), Vec3::new(1.0, 0.05, 3.5), false);
    for k in 0..10 {
        let c = Vec3::new(0.25 + 0.07 * k as f32, 0.05, 2.6);
        o.cube(c, c + Vec3::splat(0.04), false);
    }
    o.group("outside");
    o.cube(Vec3::splat(6.0), Vec3::splat(7.0), false);
    o.group("lamp");
    o.quad([
        Vec3::new(1.0, 5.0, 1.0),
        Vec3::new(1.0, 5.0, 2.0),
        Vec3::new(2.0, 5.0, 2.0),
        Vec3::new(2.0, 5.0, 1.0),
    ]);
    std::fs::write(dir.join("rooms.obj"), o.text).unwrap();
    let mut toml = String::from(
        r#"
[[materials]]
name = "white"
type = "diffuse"
reflectance = [0.7, 0.7, 0.7]

[[materials]]
name = "light"
type = "diffuse"
reflectance = [0.5, 0.5, 0.5]
emission = [10, 10, 10]

[view_space]
type = "rectangle"
min = [0.5, 2.0, 0.5]
max = [3.5, 2.0, 2.0]
"#,
    );
    for name in [
        "room", "crate", "safe", "hidden", "ball", "pebbles", "outside", "lamp",
    ] {
        let material = if name == "lamp" { "light" } else { "white" };
        write!(
            toml,
            "\n[[objects]]\nname = \"{name}\"\nmesh = \"rooms.obj\"\ngroup = \"{name}\"\nmaterial = \"{material}\"\n"
        )
        .unwrap();
    }
    std::fs::write(dir.join("scene.toml"), toml).unwrap();
    Scene::load(dir.join("scene.toml")).unwrap()
}

fn run(scene: &Scene, backend: Backend, q: f32) -> Report {
    let mut engine = accel::build(backend, &scene.geometry(), &scene.at(0.0)).unwrap();
    simplify_report(scene, engine.as_mut(), Quality::new(q).unwrap()).unwrap()
}

fn object(scene: &Scene, name: &str) -> usize {
    scene.objects.iter().position(|o| o.name == name).unwrap()
}

fn patch_area(s: &Simplified, object: usize) -> f32 {
    s.patches
        .iter()
        .filter(|p| p.object as usize == object)
        .map(|p| p.area())
        .sum()
}

fn check_invariants(scene: &Scene, r: &Report) {
    let stats = r.simplified.stats;
    let input: usize = scene.objects.iter().map(|o| o.mesh.triangles.len()).sum();
    let kept: usize = r.objects.iter().map(|o| o.kept_triangles).sum();
    assert_eq!(stats.initial_surfaces, input);
    assert_eq!(stats.initial_surfaces, stats.pruned_surfaces + kept);
    assert!(stats.final_surfaces >= kept, "{stats:?}, kept {kept}");
    assert_eq!(stats.final_surfaces, r.simplified.patches.len());
    assert_eq!(
        r.objects.iter().map(|o| o.patches).sum::<usize>(),
        stats.final_surfaces
    );
    assert!(stats.visibility_rays > 0);
    assert_eq!(r.depth_limited, 0);
    let max = r.params.max_edge * (1.0 + 1e-5);
    for p in &r.simplified.patches {
        for k in 0..3 {
            let e = p.vertices[k].distance(p.vertices[(k + 1) % 3]);
            // Only slivers at the minimum patch size keep longer edges.
            assert!(
                e <= max || p.area() <= r.params.min_patch_area,
                "edge {e} > {max} in object {}, area {}",
                p.object,
                p.area()
            );
        }
        for &c in &p.corners {
            assert_eq!(r.simplified.records[c as usize].object, p.object);
        }
    }
}

#[test]
fn counts_add_up_and_edges_respect_the_limit_on_every_backend() {
    let dir = tempfile::tempdir().unwrap();
    let scene = rooms(dir.path());
    let mut fates = Vec::new();
    for &backend in Backend::available() {
        let r = run(&scene, backend, 0.5);
        check_invariants(&scene, &r);
        fates.push(r.objects.iter().map(|o| o.fate).collect::<Vec<_>>());
    }
    // The engines agree; only where both exist (the pure-Rust build has one).
    #[cfg(feature = "embree")]
    {
        assert_eq!(fates.len(), 2);
        assert_eq!(fates[0], fates[1]);
    }
}

#[test]
fn unseen_objects_are_dropped_and_emitters_kept() {
    let dir = tempfile::tempdir().unwrap();
    let scene = rooms(dir.path());
    for q in [0.0, 1.0] {
        let r = run(&scene, Backend::default_available(), q);
        for name in ["hidden", "outside"] {
            let o = r.objects[object(&scene, name)];
            assert_eq!(
                (o.hits, o.fate, o.patches),
                (0, Fate::Unseen, 0),
                "{name} at q {q}"
            );
        }
        let lamp = object(&scene, "lamp");
        assert_eq!(r.objects[lamp].hits, 0);
        assert_eq!(r.objects[lamp].fate, Fate::Whole);
        let area = patch_area(&r.simplified, lamp);
        assert!((area - 1.0).abs() < 1e-5, "lamp area {area}");
        for name in ["room", "crate", "safe"] {
            assert!(r.objects[object(&scene, name)].hits > 0, "{name}");
        }
    }
}

#[test]
fn kept_objects_keep_their_area() {
    let dir = tempfile::tempdir().unwrap();
    let scene = rooms(dir.path());
    let r = run(&scene, Backend::default_available(), 0.5);
    let ball = object(&scene, "ball");
    assert_eq!(r.objects[ball].fate, Fate::Coarsened);
    assert!(r.objects[ball].kept_triangles < scene.objects[ball].mesh.triangles.len() / 4);
    // The pebbles go, the board stays.
    let pebbles = r.objects[object(&scene, "pebbles")];
    assert!(
        matches!(pebbles.fate, Fate::Whole | Fate::Coarsened),
        "{pebbles:?}"
    );
    assert!((1..=12).contains(&pebbles.kept_triangles), "{pebbles:?}");
    assert!((pebbles.pruned_area - 10.0 * 6.0 * 0.04 * 0.04).abs() < 1e-4);
    for (i, o) in r.objects.iter().enumerate() {
        let original = scene.objects[i].mesh.area() - o.pruned_area;
        let area = patch_area(&r.simplified, i);
        match o.fate {
            Fate::Whole => assert!(
                (area - original).abs() <= 1e-5 * original,
                "{}: {area} vs {original}",
                scene.objects[i].name
            ),
            Fate::Coarsened => assert!(
                (area - original).abs() <= AREA_TOLERANCE * original * (1.0 + 1e-4),
                "{}: {area} vs {original}",
                scene.objects[i].name
            ),
            Fate::Unseen | Fate::Small => assert_eq!(area, 0.0),
        }
    }
}

#[test]
fn higher_quality_keeps_more_and_finer_patches() {
    let dir = tempfile::tempdir().unwrap();
    let scene = rooms(dir.path());
    let runs: Vec<Report> = [0.0, 0.3, 0.6, 0.9]
        .iter()
        .map(|&q| run(&scene, Backend::default_available(), q))
        .collect();
    for w in runs.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        assert!(b.params.max_edge < a.params.max_edge);
        assert!(b.simplified.stats.final_surfaces > a.simplified.stats.final_surfaces);
        assert!(b.simplified.stats.pruned_surfaces <= a.simplified.stats.pruned_surfaces);
        assert!(b.simplified.stats.visibility_rays > a.simplified.stats.visibility_rays);
    }
}

#[test]
fn two_runs_are_identical() {
    let dir = tempfile::tempdir().unwrap();
    let scene = rooms(dir.path());
    let strip = |mut r: Report| {
        r.simplified.stats.seconds = 0.0;
        r
    };
    let a = strip(run(&scene, Backend::default_available(), 0.7));
    let b = strip(run(&scene, Backend::default_available(), 0.7));
    assert_eq!(a, b);
}

#[test]
fn a_scene_with_nothing_visible_is_an_error_naming_its_file() {
    let dir = tempfile::tempdir().unwrap();
    let mut o = Obj::default();
    o.group("box");
    o.cube(Vec3::ZERO, Vec3::ONE, false);
    std::fs::write(dir.path().join("box.obj"), o.text).unwrap();
    // No view space: the only camera stands outside the box and looks away
    // from it, so no ray hits anything and no object is kept.
    let toml = r#"
[[materials]]
name = "white"
type = "diffuse"
reflectance = [0.5, 0.5, 0.5]

[[objects]]
name = "box"
mesh = "box.obj"
material = "white"

[[cameras]]
name = "main"
position = [0.5, 0.5, 5]
direction = [0, 0, 1]
vfov = 40
"#;
    std::fs::write(dir.path().join("scene.toml"), toml).unwrap();
    let scene = Scene::load(dir.path().join("scene.toml")).unwrap();
    let mut engine = accel::build(Backend::Bvh, &scene.geometry(), &scene.at(0.0)).unwrap();
    let err = simplify(&scene, engine.as_mut(), Quality::new(0.5).unwrap()).unwrap_err();
    let msg = format!("{err:#}");
    assert!(msg.contains(&scene.source.display().to_string()), "{msg}");
    assert!(msg.contains("nothing is left"), "{msg}");
    // Turned towards the box, the camera sees it and it is kept.
    std::fs::write(
        dir.path().join("scene.toml"),
        toml.replace("direction = [0, 0, 1]", "direction = [0, 0, -1]"),
    )
    .unwrap();
    let scene = Scene::load(dir.path().join("scene.toml")).unwrap();
    let r = run(&scene, Backend::Bvh, 0.5);
    assert!(r.objects[0].hits > 0);
    assert_eq!(r.objects[0].fate, Fate::Whole);
}

#[test]
fn bisected_walls_share_the_records_of_their_common_edges() {
    let dir = tempfile::tempdir().unwrap();
    let scene = rooms(dir.path());
    let r = run(&scene, Backend::default_available(), 0.8);
    let room = object(&scene, "room");
    assert!(r.objects[room].patches > 12 * 16, "{:?}", r.objects[room]);
    // In a conforming triangulation of the cube's faces every edge inside a
    // face is shared by two patches (same two records); the edges used once
    // are the faces' borders, 6 x 16 m long. A T-junction would add more.
    let mut edges = std::collections::HashMap::new();
    for p in r
        .simplified
        .patches
        .iter()
        .filter(|p| p.object as usize == room)
    {
        for k in 0..3 {
            let (a, b) = (p.corners[k], p.corners[(k + 1) % 3]);
            let len = p.vertices[k].distance(p.vertices[(k + 1) % 3]);
            edges.entry((a.min(b), a.max(b))).or_insert((0, len)).0 += 1;
        }
    }
    assert!(edges.values().all(|&(n, _)| n <= 2));
    let border: f32 = edges
        .values()
        .filter(|&&(n, _)| n == 1)
        .map(|&(_, l)| l)
        .sum();
    assert!((border - 96.0).abs() < 1e-3, "border {border}");
}

#[test]
fn studio_patch_counts_suit_the_solver() {
    let scene = Scene::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/studio/scene.toml"
    ))
    .unwrap();
    for (q, lo, hi) in [
        (0.3, 2_000, 5_000),
        (0.6, 5_000, 10_000),
        (0.9, 5_000, 20_000),
    ] {
        let r = run(&scene, Backend::default_available(), q);
        let s = r.simplified.stats;
        eprintln!("q {q}: {s:?}");
        for (o, rep) in scene.objects.iter().zip(&r.objects) {
            eprintln!("   {:12} {:?}", o.name, rep);
        }
        check_invariants(&scene, &r);
        assert!(s.initial_surfaces >= 50_000);
        assert!((lo..=hi).contains(&s.final_surfaces), "q {q}: {s:?}");
    }
}

#[test]
fn the_cornell_box_simplifies_alike_at_every_scale() {
    let load = |name: &str| {
        Scene::load(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("scenes")
                .join(name)
                .join("scene.toml"),
        )
        .unwrap()
    };
    let base = load("cornell-box");
    let r = run(&base, Backend::default_available(), 0.6);
    check_invariants(&base, &r);
    let light = object(&base, "light");
    assert_eq!(r.objects[light].fate, Fate::Whole);
    let fates: Vec<Fate> = r.objects.iter().map(|o| o.fate).collect();
    for (name, scale) in [("cornell-box-1e-4", 1e-4), ("cornell-box-1e4", 1e4)] {
        let scene = load(name);
        let s = run(&scene, Backend::default_available(), 0.6);
        check_invariants(&scene, &s);
        assert_eq!(s.objects.iter().map(|o| o.fate).collect::<Vec<_>>(), fates);
        assert_eq!(
            s.simplified.stats.final_surfaces, r.simplified.stats.final_surfaces,
            "{name}"
        );
        let ratio = s.params.max_edge / r.params.max_edge / scale;
        assert!((ratio - 1.0).abs() < 1e-3, "{name}: {ratio}");
    }
}
