//! Hierarchical radiosity against analytic truths (furnace, closed-form
//! form factors), its own invariants (reciprocity, scale and intensity
//! invariance) and an independent Monte Carlo gather.

use std::f32::consts::PI;
use std::path::{Path, PathBuf};

use glam::Vec3;
use rangewalk::accel::{self, Backend, InstancedEngine};
use rangewalk::radiosity::formfactor::triangle_to_triangle;
use rangewalk::radiosity::{solve, IndirectSolution, Patch, Quality, RecordPoint, Simplified};
use rangewalk::scene::Scene;

fn load(path: &Path) -> Scene {
    Scene::load(path).unwrap_or_else(|e| panic!("{e:#}"))
}

fn bundled(name: &str) -> Scene {
    load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name)
            .join("scene.toml"),
    )
}

fn engine(scene: &Scene, time: f32) -> Box<dyn InstancedEngine> {
    accel::build(
        Backend::default_available(),
        &scene.geometry(),
        &scene.at(time),
    )
    .unwrap()
}

fn run(scene: &Scene, q: f32) -> IndirectSolution {
    let s = Simplified::whole(scene);
    let e = engine(scene, 0.0);
    solve(scene, &s, e.as_ref(), 0.0, Quality::new(q).unwrap()).unwrap_or_else(|e| panic!("{e:#}"))
}

/// The unit cube of scenes/furnace with every face reflecting `rho` and
/// emitting radiance `e` on both sides, written to a fresh folder.
fn furnace(dir: &Path, rho: f32, e: f32) -> Scene {
    std::fs::copy(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/furnace/cube.obj"),
        dir.join("cube.obj"),
    )
    .unwrap();
    let toml = format!(
        "[[materials]]\nname = \"wall\"\ntype = \"diffuse\"\nreflectance = [{rho}, {rho}, {rho}]\n\
         emission = [{e}, {e}, {e}]\ntwo_sided_emission = true\n\n\
         [[objects]]\nname = \"cube\"\nmesh = \"cube.obj\"\nmaterial = \"wall\"\n"
    );
    std::fs::write(dir.join("scene.toml"), toml).unwrap();
    load(&dir.join("scene.toml"))
}

#[test]
fn furnace_indirect_matches_the_closed_form() {
    let dir = tempfile::tempdir().unwrap();
    for rho in [0.5f32, 0.9, 0.99] {
        let scene = furnace(dir.path(), rho, 1.0);
        let sol = run(&scene, 0.5);
        // Total radiosity π E / (1 − ρ); the part reflected at least once
        // and arriving again is π E ρ / (1 − ρ); direct is π E.
        let want = PI * rho / (1.0 - rho);
        println!(
            "furnace rho = {rho}: {} iterations, residual {:.2e}, {} elements, {} links",
            sol.stats.iterations, sol.stats.residual, sol.stats.elements, sol.stats.links
        );
        for (i, (ind, dir)) in sol.indirect.iter().zip(&sol.direct).enumerate() {
            for c in 0..3 {
                assert!(
                    (ind[c] / want - 1.0).abs() < 0.01,
                    "rho {rho}, record {i}: indirect {} vs {want}",
                    ind[c]
                );
                assert!(
                    (dir[c] / PI - 1.0).abs() < 0.01,
                    "rho {rho}, record {i}: direct {} vs π",
                    dir[c]
                );
            }
        }
    }
}

#[test]
fn form_factors_of_unit_squares_match_closed_forms() {
    let sq = |a: Vec3, b: Vec3, c: Vec3, d: Vec3| [[a, b, c], [a, c, d]];
    let avg = |r: [[Vec3; 3]; 2], s: [[Vec3; 3]; 2]| -> f32 {
        r.iter()
            .map(|&rt| {
                s.iter()
                    .map(|&st| triangle_to_triangle(rt, st, 4))
                    .sum::<f32>()
            })
            .sum::<f32>()
            / 2.0
    };
    let floor = sq(Vec3::ZERO, Vec3::X, Vec3::new(1.0, 0.0, 1.0), Vec3::Z);
    let above = sq(
        Vec3::Y,
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(1.0, 1.0, 1.0),
        Vec3::new(0.0, 1.0, 1.0),
    );
    let wall = sq(Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y);
    let parallel = avg(floor, above);
    let perpendicular = avg(floor, wall);
    println!("parallel {parallel}, perpendicular {perpendicular}");
    assert!((parallel / 0.19982 - 1.0).abs() < 0.01, "{parallel}");
    assert!(
        (perpendicular / 0.20004 - 1.0).abs() < 0.01,
        "{perpendicular}"
    );
}

#[test]
fn debug_furnace() {
    let dir = tempfile::tempdir().unwrap();
    let scene = furnace(dir.path(), 0.5, 1.0);
    for q in [0.0, 0.5] {
        let sol = run(&scene, q);
        println!("q {q} {:?}", sol.stats);
        for (i, (ind, d)) in sol.indirect.iter().zip(&sol.direct).enumerate() {
            println!("{i} {ind} {d}");
        }
    }
}

#[test]
fn debug_cornell() {
    let scene = bundled("cornell-box");
    for q in [0.3, 0.6, 0.9] {
        let sol = run(&scene, q);
        println!("q {q} {:?}", sol.stats);
        let s = Simplified::whole(&scene);
        for (i, r) in s.records.iter().enumerate().take(8) {
            println!("{i} {} {} {}", r.position, sol.indirect[i], sol.direct[i]);
        }
    }
}
