//! Hierarchical radiosity against analytic truths (furnace, closed-form
//! form factors), its own invariants (reciprocity, scale and intensity
//! invariance) and an independent Monte Carlo gather.

use std::f32::consts::PI;
use std::path::{Path, PathBuf};

use glam::Vec3;
use rangewalk::accel::RayEngine;
use rangewalk::quality::Quality;
use rangewalk::radiosity::formfactor::triangle_to_triangle;
use rangewalk::radiosity::{
    diffuse_albedo, solve, IndirectSolution, Patch, RecordPoint, Simplified,
};
use rangewalk::ray::{offset_origin, Ray};
use rangewalk::scene::{Light, Scene};
use rayon::prelude::*;

mod common;
use common::{engine_at as engine, load_path as load};

fn bundled(name: &str) -> Scene {
    load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name)
            .join("scene.toml"),
    )
}

fn run(scene: &Scene, q: f32) -> IndirectSolution {
    let s = Simplified::whole(scene);
    let e = engine(scene, 0.0);
    solve(scene, &s, e.as_ref(), 0.0, Quality::new(q).unwrap()).unwrap_or_else(|e| panic!("{e:#}"))
}

/// The unit cube of scenes/furnace with every face reflecting `rho` and
/// emitting radiance `e` on both sides, written to a fresh folder.
fn furnace(dir: &Path, rho: f32, e: f32) -> Scene {
    furnace_of(
        dir,
        &format!("type = \"diffuse\"\nreflectance = [{rho}, {rho}, {rho}]"),
        e,
    )
}

/// The same furnace with the material fields (type and reflectances) given.
fn furnace_of(dir: &Path, material: &str, e: f32) -> Scene {
    std::fs::copy(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/furnace/cube.obj"),
        dir.join("cube.obj"),
    )
    .unwrap();
    let toml = format!(
        "[[materials]]\nname = \"wall\"\n{material}\n\
         emission = [{e}, {e}, {e}]\ntwo_sided_emission = true\n\n\
         [[objects]]\nname = \"cube\"\nmesh = \"cube.obj\"\nmaterial = \"wall\"\n"
    );
    std::fs::write(dir.join("scene.toml"), toml).unwrap();
    load(&dir.join("scene.toml"))
}

/// Which records see light in the furnace scenes: all but those of the
/// outer unit cube (object 0) that face away from its centre, into empty
/// space, where nothing reaches them.
fn facing_in(scene: &Scene) -> Vec<bool> {
    Simplified::whole(scene)
        .records
        .iter()
        .map(|r| r.object != 0 || r.normal.dot(Vec3::splat(0.5) - r.position) > 0.0)
        .collect()
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
        let lit = facing_in(&scene);
        for (i, (ind, dir)) in sol.indirect.iter().zip(&sol.direct).enumerate() {
            if !lit[i] {
                assert_eq!((*ind, *dir), (Vec3::ZERO, Vec3::ZERO), "record {i}");
                continue;
            }
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

/// Inside a closed furnace the radiance is the same everywhere and in
/// every direction, so any surface reflects its white-sky albedo `a` of
/// it, whichever way its lobes send the light: indirect irradiance is
/// π E a / (1 − a) exactly. A transport that keeps only the diffuse part
/// `d` of glossy surfaces gives π E d / (1 − d) instead: 8% of the exact
/// value for the GGX walls below, 13% for the Ward ones.
#[test]
fn glossy_furnaces_keep_all_reflected_light() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "ggx",
            "type = \"glossy\"\nmodel = \"ggx\"\ndiffuse = [0.3, 0.3, 0.3]\n\
             specular = [0.6, 0.6, 0.6]\nroughness = 0.3",
        ),
        (
            "ward",
            "type = \"glossy\"\nmodel = \"ward\"\ndiffuse = [0.2, 0.2, 0.2]\n\
             specular = [0.5, 0.5, 0.5]\nroughness = 0.2",
        ),
    ];
    for (name, material) in cases {
        let scene = furnace_of(dir.path(), material, 1.0);
        let (a, sigma) = white_sky_albedo(&scene.materials[0].bsdf);
        let sol = run(&scene, 0.5);
        let want = PI * a / (1.0 - a);
        // The albedo's Monte Carlo error (4σ), carried through a / (1 − a),
        // plus the 1% the diffuse furnace is held to.
        let tol = 0.01 + 4.0 * sigma / (a * (1.0 - a));
        let d = diffuse_albedo(&scene.materials[0].bsdf).x;
        println!(
            "{name}: albedo {a} ± {sigma}, tolerance {tol}; diffuse only would give {}",
            d / (1.0 - d) / (a / (1.0 - a))
        );
        let lit = facing_in(&scene);
        for (i, ind) in sol.indirect.iter().enumerate().filter(|&(i, _)| lit[i]) {
            assert!(
                (ind.x / want - 1.0).abs() < tol,
                "{name} furnace (albedo {a}), record {i}: indirect {} vs {want}",
                ind.x
            );
        }
    }
}

/// White-sky albedo of a material (red channel) and its standard error, by
/// uniform sampling of both directions and the BSDF's evaluation alone
/// (independent of the lobes' samplers).
fn white_sky_albedo(bsdf: &rangewalk::scene::Bsdf) -> (f32, f32) {
    use rangewalk::bsdf::Lobes;
    let lobes = Lobes::at(bsdf, None);
    let mut rng = Rng(11);
    let mut uniform = || {
        let (z, phi) = (rng.next(), 2.0 * PI * rng.next());
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    };
    let n = 2_000_000;
    let (mut sum, mut sq) = (0.0f64, 0.0f64);
    for _ in 0..n {
        let (wo, wi) = (uniform(), uniform());
        // a = (1/π) ∫∫ f cos cos over two hemispheres of 2π each.
        let v = (lobes.eval(wo, wi).x * wo.z * wi.z * 4.0 * PI) as f64;
        sum += v;
        sq += v * v;
    }
    let mean = sum / n as f64;
    let var = (sq / n as f64 - mean * mean).max(0.0);
    (mean as f32, (var / n as f64).sqrt() as f32)
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
fn reflectance_of_one_is_an_error_naming_the_object() {
    let dir = tempfile::tempdir().unwrap();
    let scene = furnace(dir.path(), 0.5, 1.0);
    let v = [Vec3::ZERO, Vec3::X, Vec3::Y];
    for rho in [1.0, f32::NAN] {
        let s = Simplified {
            patches: vec![Patch {
                object: 0,
                vertices: v,
                corners: [0, 1, 2],
                back: [0, 1, 2],
                reflectance: Vec3::new(0.5, rho, 0.5),
                emission: Vec3::ONE,
                two_sided: false,
            }],
            records: v
                .iter()
                .map(|&position| RecordPoint {
                    object: 0,
                    position,
                    normal: Vec3::Z,
                })
                .collect(),
            pruned: Vec::new(),
            stats: Default::default(),
        };
        let e = engine(&scene, 0.0);
        let err = solve(&scene, &s, e.as_ref(), 0.0, Quality::new(0.5).unwrap())
            .expect_err("reflectance 1 must be refused");
        let msg = format!("{err:#}");
        assert!(
            msg.contains("`cube`") && msg.contains("reflectance"),
            "{msg}"
        );
    }
}

/// Unoccluded area-averaged form factors between the Cornell box's patches
/// obey reciprocity; within the open room (walls, floor, ceiling: nothing
/// in between) rows sum to at most one.
#[test]
fn cornell_form_factors_are_reciprocal_and_rows_sum_below_one() {
    let scene = bundled("cornell-box");
    let s = Simplified::whole(&scene);
    let tris: Vec<[Vec3; 3]> = s.patches.iter().map(|p| p.vertices).collect();
    let area = |t: &[Vec3; 3]| 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length();
    let n = tris.len();
    let f: Vec<Vec<f32>> = (0..n)
        .into_par_iter()
        .map(|i| {
            (0..n)
                .map(|j| {
                    if i == j {
                        0.0
                    } else {
                        triangle_to_triangle(tris[i], tris[j], 4)
                    }
                })
                .collect()
        })
        .collect();
    let mut worst = 0.0f32;
    let room: Vec<usize> = (0..n).filter(|&i| s.patches[i].object <= 4).collect();
    for &i in &room {
        let row: f32 = room.iter().map(|&j| f[i][j]).sum();
        assert!(row <= 1.0 + 1e-4, "row {i} sums to {row}");
        assert!(row > 0.5, "row {i} sums to only {row}");
    }
    // The light hangs 0.5 mm under the ceiling: no receiver quadrature
    // resolves a pair that close, and the solver splits it instead.
    let light = |i: usize| s.patches[i].object == 5;
    for i in (0..n).filter(|&i| !light(i)) {
        for j in (0..i).filter(|&j| !light(j)) {
            let (a, b) = (area(&tris[i]) * f[i][j], area(&tris[j]) * f[j][i]);
            let scale = area(&tris[i]).max(area(&tris[j]));
            // Relative to the larger patch: pairs that barely see each
            // other carry no weight.
            let err = (a - b).abs() / scale;
            worst = worst.max(err);
            assert!(
                err < 2e-3,
                "A_i F_ij {a} vs A_j F_ji {b} for patches {i}, {j}"
            );
        }
    }
    println!("worst reciprocity error {worst:.2e} over {n} patches");
}

fn relative_rms(a: &[Vec3], b: &[Vec3]) -> f32 {
    let num: f32 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length_squared())
        .sum();
    let den: f32 = b.iter().map(|y| y.length_squared()).sum();
    (num / den).sqrt()
}

fn assert_finite(sol: &IndirectSolution) {
    for v in sol.indirect.iter().chain(&sol.direct) {
        assert!(v.is_finite() && v.min_element() >= 0.0, "{v}");
    }
}

#[test]
fn scaled_cornell_boxes_give_the_same_solution() {
    let q = 0.6;
    let base = run(&bundled("cornell-box"), q);
    assert_finite(&base);
    for name in ["cornell-box-1e-4", "cornell-box-1e4"] {
        let sol = run(&bundled(name), q);
        assert_finite(&sol);
        // Irradiance of the same radiances does not depend on scale.
        let (ei, ed) = (
            relative_rms(&sol.indirect, &base.indirect),
            relative_rms(&sol.direct, &base.direct),
        );
        println!("{name}: relative RMS indirect {ei:.2e}, direct {ed:.2e}");
        assert!(ei < 0.02 && ed < 0.02, "{name}: {ei} {ed}");
    }
}

#[test]
fn light_intensity_scales_the_solution_linearly() {
    let mut scene = bundled("cornell-box");
    let base = run(&scene, 0.5);
    let light = scene
        .materials
        .iter()
        .position(|m| m.emission.is_some())
        .unwrap();
    let radiance = scene.materials[light].emission.unwrap().radiance;
    for k in [1e-6f32, 1e8] {
        scene.materials[light].emission.as_mut().unwrap().radiance = radiance * k;
        let sol = run(&scene, 0.5);
        assert_finite(&sol);
        let scaled: Vec<Vec3> = sol.indirect.iter().map(|v| *v / k).collect();
        let e = relative_rms(&scaled, &base.indirect);
        assert!(e < 1e-3, "scale {k}: relative RMS {e}");
    }
    // Point lights and the sun from 1e-6 to 1e8, alone: finite, and linear.
    scene.materials[light].emission = None;
    let mut prev: Option<Vec<Vec3>> = None;
    for k in [1e-6f32, 1e8] {
        scene.lights = vec![
            Light::Point {
                position: Vec3::new(278.0, 400.0, 280.0),
                intensity: Vec3::new(1.0, 0.8, 0.6) * k,
            },
            Light::Sun {
                direction: Vec3::new(0.2, 1.0, -0.5),
                radiance: Vec3::splat(k),
                angular_diameter_deg: 0.53,
            },
        ];
        let sol = run(&scene, 0.5);
        assert_finite(&sol);
        assert!(sol.indirect.iter().any(|v| v.max_element() > 0.0));
        let scaled: Vec<Vec3> = sol.indirect.iter().map(|v| *v / k).collect();
        if let Some(p) = &prev {
            let e = relative_rms(&scaled, p);
            assert!(
                e < 1e-3,
                "point light and sun scaled by {k}: relative RMS {e}"
            );
        }
        prev = Some(scaled);
    }
}

/// A small deterministic random stream for the Monte Carlo reference.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32) / (1u64 << 24) as f32
    }
}

fn cosine_direction(n: Vec3, rng: &mut Rng) -> Vec3 {
    let (u1, u2) = (rng.next(), rng.next());
    let r = u1.sqrt();
    let phi = 2.0 * PI * u2;
    let t = if n.x.abs() > 0.5 { Vec3::Y } else { Vec3::X };
    let b1 = n.cross(t).normalize();
    let b2 = n.cross(b1);
    (b1 * r * phi.cos() + b2 * r * phi.sin() + n * (1.0 - u1).max(0.0).sqrt()).normalize()
}

/// Indirect irradiance at `x` (unit normal `n`) by path tracing with next
/// event estimation on the emitting triangles: Σ_k ρ_1⋯ρ_k E_direct(y_k)
/// along cosine-sampled paths, with the standard error of its channel sum.
/// Uses the ray engine and the scene only.
fn monte_carlo_indirect_with_error(
    scene: &Scene,
    engine: &dyn RayEngine,
    x: Vec3,
    n: Vec3,
    paths: usize,
) -> (Vec3, f32) {
    let poses = scene.at(0.0);
    let mut emitters = Vec::new();
    for (o, xf) in scene.objects.iter().zip(&poses) {
        if let Some(e) = scene.materials[o.material].emission {
            for t in &o.mesh.triangles {
                let v = t.map(|i| xf.transform_point3(o.mesh.positions[i as usize]));
                emitters.push((v, e));
            }
        }
    }
    let area = |v: &[Vec3; 3]| 0.5 * (v[1] - v[0]).cross(v[2] - v[0]).length();
    let total: f32 = emitters.iter().map(|(v, _)| area(v)).sum();
    let direct = |y: Vec3, ny: Vec3, rng: &mut Rng| -> Vec3 {
        let mut pick = rng.next() * total;
        let (v, e) = emitters
            .iter()
            .find(|(v, _)| {
                pick -= area(v);
                pick <= 0.0
            })
            .unwrap_or(emitters.last().unwrap());
        let (mut a, mut b) = (rng.next(), rng.next());
        if a + b > 1.0 {
            (a, b) = (1.0 - a, 1.0 - b);
        }
        let p = v[0] + (v[1] - v[0]) * a + (v[2] - v[0]) * b;
        let nl = (v[1] - v[0]).cross(v[2] - v[0]).normalize();
        let d = p - y;
        let d2 = d.length_squared();
        let w = d / d2.sqrt();
        let (cy, cl) = (ny.dot(w), -nl.dot(w));
        let cl = if e.two_sided { cl.abs() } else { cl };
        if cy <= 0.0 || cl <= 0.0 {
            return Vec3::ZERO;
        }
        let o = offset_origin(y, ny, d);
        let t = offset_origin(p, nl, -d);
        if engine.occluded(&Ray::segment(o, t - o, 1.0)) {
            return Vec3::ZERO;
        }
        e.radiance * (cy * cl / d2 * total)
    };
    let (sum, sq): (Vec3, f64) = (0..paths)
        .into_par_iter()
        .map(|i| {
            let mut rng = Rng((i as u64).wrapping_mul(0x9e3779b97f4a7c15) ^ 7);
            let (mut p, mut np) = (x, n);
            let mut beta = Vec3::ONE;
            let mut est = Vec3::ZERO;
            for bounce in 0..64 {
                let w = cosine_direction(np, &mut rng);
                let Some(hit) = engine.intersect(&Ray::new(offset_origin(p, np, w), w)) else {
                    break;
                };
                let y = offset_origin(p, np, w) + w * hit.t;
                let ny = if hit.normal.dot(w) < 0.0 {
                    hit.normal
                } else {
                    -hit.normal
                };
                let rho = diffuse_albedo(&scene.material_of(hit.object).bsdf);
                beta *= rho;
                est += beta * direct(y, ny, &mut rng);
                if bounce >= 2 {
                    let survive = beta.max_element().min(0.95);
                    if rng.next() >= survive {
                        break;
                    }
                    beta /= survive;
                }
                (p, np) = (y, ny);
            }
            (est, (est.element_sum() as f64).powi(2))
        })
        .reduce(|| (Vec3::ZERO, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    let mean = sum / paths as f32;
    let m = mean.element_sum() as f64;
    let var = (sq / paths as f64 - m * m).max(0.0);
    (mean, (var / paths as f64).sqrt() as f32)
}

/// A closed room lit only through a skylight by a lamp above the roof: the
/// ceiling's outside is lit directly and brightly, its inside only by light
/// the floor and walls reflect. Each side must keep its own records; with
/// one record per corner, the brighter outside was reported and the inside
/// of a sunlit room came out black.
#[test]
fn a_ceiling_lit_from_outside_keeps_its_inside_dark_only_where_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let mut obj = String::new();
    let mut quad = |group: &str, c: [[f32; 3]; 4]| {
        obj.push_str(&format!("o {group}\n"));
        for v in c {
            obj.push_str(&format!("v {} {} {}\n", v[0], v[1], v[2]));
        }
        obj.push_str("f -4 -3 -2 -1\n");
    };
    let (w, h) = (4.0, 3.0);
    quad(
        "floor",
        [[0.0, 0.0, 0.0], [0.0, 0.0, w], [w, 0.0, w], [w, 0.0, 0.0]],
    );
    quad(
        "walls",
        [[0.0, 0.0, 0.0], [w, 0.0, 0.0], [w, h, 0.0], [0.0, h, 0.0]],
    );
    quad(
        "walls",
        [[0.0, 0.0, w], [0.0, h, w], [w, h, w], [w, 0.0, w]],
    );
    quad(
        "walls",
        [[0.0, 0.0, 0.0], [0.0, h, 0.0], [0.0, h, w], [0.0, 0.0, w]],
    );
    quad(
        "walls",
        [[w, 0.0, 0.0], [w, 0.0, w], [w, h, w], [w, h, 0.0]],
    );
    // The ceiling around a 1 m skylight in its middle.
    for [x0, z0, x1, z1] in [
        [0.0, 0.0, w, 1.5],
        [0.0, 2.5, w, w],
        [0.0, 1.5, 1.5, 2.5],
        [2.5, 1.5, w, 2.5],
    ] {
        quad(
            "ceiling",
            [[x0, h, z0], [x1, h, z0], [x1, h, z1], [x0, h, z1]],
        );
    }
    // Facing down onto the roof and through the skylight.
    quad(
        "lamp",
        [
            [1.0, 3.5, 1.0],
            [3.0, 3.5, 1.0],
            [3.0, 3.5, 3.0],
            [1.0, 3.5, 3.0],
        ],
    );
    std::fs::write(dir.path().join("room.obj"), obj).unwrap();
    let mut toml = String::from(
        "[[materials]]\nname = \"white\"\ntype = \"diffuse\"\nreflectance = [0.7, 0.7, 0.7]\n\n\
         [[materials]]\nname = \"lamp\"\ntype = \"diffuse\"\nreflectance = [0, 0, 0]\nemission = [10, 10, 10]\n",
    );
    for (name, material) in [
        ("floor", "white"),
        ("walls", "white"),
        ("ceiling", "white"),
        ("lamp", "lamp"),
    ] {
        toml.push_str(&format!(
            "\n[[objects]]\nname = \"{name}\"\nmesh = \"room.obj\"\ngroup = \"{name}\"\nmaterial = \"{material}\"\n"
        ));
    }
    std::fs::write(dir.path().join("scene.toml"), toml).unwrap();
    let scene = load(&dir.path().join("scene.toml"));
    let ceiling = scene
        .objects
        .iter()
        .position(|o| o.name == "ceiling")
        .unwrap() as u32;
    let mut e = engine(&scene, 0.0);
    let quality = Quality::new(0.5).unwrap();
    let s = rangewalk::radiosity::simplify(&scene, e.as_mut(), quality).unwrap();
    let sol = solve(&scene, &s, e.as_ref(), 0.0, quality).unwrap();
    let (mut inside, mut outside) = (Vec::new(), Vec::new());
    for (k, r) in s.records.iter().enumerate() {
        if r.object == ceiling {
            let side = if r.normal.y < 0.0 {
                &mut inside
            } else {
                &mut outside
            };
            side.push((k, r.position));
        }
    }
    assert!(!inside.is_empty() && inside.len() == outside.len());
    // The lamp is behind the inside's plane: no direct light there at all,
    // and some indirect light everywhere.
    for &(k, p) in &inside {
        assert_eq!(sol.direct[k], Vec3::ZERO, "inside at {p}");
        assert!(sol.indirect[k].x > 0.0, "inside at {p}: no indirect light");
    }
    let lit_outside = outside
        .iter()
        .filter(|&&(k, _)| sol.direct[k].x > 0.0)
        .count();
    assert!(
        lit_outside > outside.len() / 2,
        "{lit_outside} of {} outside records lit",
        outside.len()
    );
    // One inside record against the Monte Carlo gather (19% low measured,
    // the occluder bias noted at `MC_TOLERANCE`).
    let &(k, p) = inside
        .iter()
        .min_by(|a, b| {
            a.1.distance(Vec3::new(1.0, h, 1.0))
                .total_cmp(&b.1.distance(Vec3::new(1.0, h, 1.0)))
        })
        .unwrap();
    let (mc, sigma) = monte_carlo_indirect_with_error(&scene, e.as_ref(), p, -Vec3::Y, 40_000);
    let (mc, hr) = (mc.element_sum(), sol.indirect[k].element_sum());
    println!("ceiling inside at {p}: radiosity {hr}, Monte Carlo {mc} ± {sigma}");
    // The goal of the Cornell box's records (10%) plus the gather's error.
    assert!(
        (hr - mc).abs() <= 0.1 * mc + 3.0 * sigma,
        "radiosity {hr} vs Monte Carlo {mc} ± {sigma}"
    );
}

/// The whole object-space pipeline (simplification once, then a solve per
/// time on its patches, with every occluder in place) against the Monte
/// Carlo gather at the records nearest to points in the open, in the boxes'
/// shadows, at their contact edges, behind them and on them, at three times
/// of the animation. The goal is 10% at q = 0.6; the Monte Carlo estimate's
/// own error (three standard errors) is added to it.
///
/// Points on the floor within a few centimetres of a box's base are
/// printed but not held to the goal: there the records, a patch's corners,
/// carry their leaf's average over an irradiance that falls to zero at the
/// contact line, and they come out up to 17% low (47% where the short box
/// reaches the open front); docs/radiosity.md tells why.
///
/// The tall box's front face a fifth of its height above the floor (a
/// near-base point, printed as such) is held to the goal at both
/// qualities: within a few centimetres of the contact line its leaves
/// average a steep fall of light, and it is the point most likely to miss.
///
/// This check once had to leave the tall box out: the simplification left
/// the ray engine posed at a random time of the animation, and the solve
/// then saw the boxes where they were not (records beside them a third too
/// dark). The short box's top came out a sixth too dark while it shared
/// flat clusters with the floor (see `links::spans_planes`).
#[test]
fn cornell_records_agree_with_monte_carlo_with_every_occluder() {
    let scene = bundled("cornell-box");
    let id = |name: &str| scene.objects.iter().position(|o| o.name == name).unwrap();
    let (floor, short, tall) = (id("floor"), id("short-box"), id("tall-box"));
    // (object the record is on, object whose pose carries the point, point
    // and the side's normal in that object's space at t = 0, where it is)
    #[derive(Clone, Copy, PartialEq)]
    enum Place {
        Open,
        /// Low on a box face: held to the goal, printed apart.
        NearBase,
        /// Printed, never held to the goal.
        Contact,
    }
    use Place::*;
    let (up, down) = (Vec3::Y, -Vec3::Y);
    let points = [
        (floor, floor, Vec3::new(450.0, 0.0, 120.0), up, Open),
        (floor, floor, Vec3::new(100.0, 0.0, 400.0), up, Open),
        // Between the tall box and the back wall, in its shadow.
        (floor, tall, Vec3::new(420.0, 0.0, 480.0), up, Open),
        // Contact edges: just outside the boxes' front faces.
        (floor, short, Vec3::new(205.0, 0.0, 60.0), up, Contact),
        (floor, tall, Vec3::new(340.0, 0.0, 250.0), up, Contact),
        (
            id("ceiling"),
            id("ceiling"),
            Vec3::new(400.0, 548.8, 450.0),
            down,
            Open,
        ),
        (
            id("back"),
            id("back"),
            Vec3::new(150.0, 380.0, 559.2),
            -Vec3::Z,
            Open,
        ),
        (
            id("back"),
            id("back"),
            Vec3::new(412.0, 103.0, 559.2),
            -Vec3::Z,
            Open,
        ),
        (
            id("green-wall"),
            id("green-wall"),
            Vec3::new(0.0, 300.0, 150.0),
            Vec3::X,
            Open,
        ),
        (short, short, Vec3::new(185.0, 165.0, 169.0), up, Open),
        (
            short,
            short,
            Vec3::new(265.0, 82.0, 193.0),
            Vec3::new(0.95, 0.0, 0.3),
            Open,
        ),
        (tall, tall, Vec3::new(368.0, 330.0, 351.0), up, Open),
        (
            tall,
            tall,
            Vec3::new(393.0, 165.0, 431.0),
            Vec3::new(0.3, 0.0, 0.95),
            Open,
        ),
        (
            tall,
            tall,
            Vec3::new(344.0, 60.0, 272.0),
            Vec3::new(-0.3, 0.0, -0.96),
            NearBase,
        ),
    ];
    let mut e = engine(&scene, 0.0);
    let mut failures = Vec::new();
    for q in [0.6, 0.9] {
        let quality = Quality::new(q).unwrap();
        let s = rangewalk::radiosity::simplify(&scene, e.as_mut(), quality).unwrap();
        for t in [0.0, 0.5, 1.0] {
            e.set_transforms(&scene.at(t)).unwrap();
            let sol = solve(&scene, &s, e.as_ref(), t, quality).unwrap();
            let poses = scene.at(t);
            println!(
                "q = {q}, t = {t}: {} patches, {:?}",
                s.patches.len(),
                sol.stats
            );
            for &(obj, carrier, local, normal, place) in &points {
                // The point in the record object's space at time t.
                let world = poses[carrier].transform_point3(local);
                let p = poses[obj].inverse().transform_point3(world);
                let want = poses[carrier].transform_vector3(normal.normalize());
                let want = poses[obj].inverse().transform_vector3(want);
                let r = (0..s.records.len())
                    .filter(|&r| {
                        let rec = &s.records[r];
                        rec.object == obj as u32 && rec.normal.dot(want) > 0.9
                    })
                    .min_by(|&a, &b| {
                        let d = |r: usize| s.records[r].position.distance(p);
                        d(a).total_cmp(&d(b))
                    })
                    .unwrap();
                let rec = s.records[r];
                let x = poses[obj].transform_point3(rec.position);
                let n = poses[obj].transform_vector3(rec.normal).normalize();
                let (mc, sigma) = monte_carlo_indirect_with_error(&scene, e.as_ref(), x, n, 40_000);
                let (mc, hr) = (mc.element_sum(), sol.indirect[r].element_sum());
                let tol = 0.1 * mc + 3.0 * sigma;
                println!(
                    "  {}{} at {x}: radiosity {hr:.4}, Monte Carlo {mc:.4} ± {sigma:.4}, {:+.3}",
                    scene.objects[obj].name,
                    match place {
                        Open => "",
                        NearBase => " (near the base)",
                        Contact => " (contact edge)",
                    },
                    hr / mc - 1.0
                );
                let held = place != Contact;
                if held && (hr - mc).abs() > tol {
                    failures.push(format!(
                        "q = {q}, t = {t}, {} at {x}: radiosity {hr} vs Monte Carlo {mc} ± {sigma}",
                        scene.objects[obj].name
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The furnace's unit cube (`outer`) with a cube of side 0.4 inside
/// (`inner`): floating at the centre, or `standing` on the floor as a box
/// with an open bottom.
fn furnace_with_inner_cube(standing: bool) -> String {
    let mut obj = String::from("o outer\n");
    let cube = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/furnace/cube.obj"),
    )
    .unwrap();
    for line in cube
        .lines()
        .filter(|l| l.starts_with("v ") || l.starts_with("f "))
    {
        obj.push_str(line);
        obj.push('\n');
    }
    obj.push_str("o inner\n");
    for line in cube.lines().filter(|l| l.starts_with("v ")) {
        let v: Vec<f32> = line[2..]
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect();
        let m = |x: f32| 0.3 + 0.4 * x;
        let y = if standing { 0.5 * v[1] } else { m(v[1]) };
        obj.push_str(&format!("v {} {} {}\n", m(v[0]), y, m(v[2])));
    }
    // The face at y = 0 is the standing box's open bottom.
    let bottom = "f 1 5 6 2";
    for line in cube.lines().filter(|l| l.starts_with("f ")) {
        if standing && line.trim() == bottom {
            continue;
        }
        let idx: Vec<u32> = line[2..]
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect();
        obj.push('f');
        for i in idx {
            obj.push_str(&format!(" {}", i + 8));
        }
        obj.push('\n');
    }
    obj
}

/// A cube that reflects (nearly) all it receives leaves a furnace
/// (nearly) uniform, whether or not the solve has patches for it: left out
/// by the simplification, it must still hand on the light it intercepts.
/// Made black, as the solver once made it, it left the worst outer record
/// 32% dark (0.75% as it is).
#[test]
fn furnace_keeps_what_a_left_out_cube_reflects() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("cube.obj"), furnace_with_inner_cube(false)).unwrap();
    let (rho, inner) = (0.5, 0.98);
    let toml = format!(
        "[[materials]]\nname = \"wall\"\ntype = \"diffuse\"\nreflectance = [{rho}, {rho}, {rho}]\n\
         emission = [1, 1, 1]\ntwo_sided_emission = true\n\n\
         [[materials]]\nname = \"white\"\ntype = \"diffuse\"\nreflectance = [{inner}, {inner}, {inner}]\n\n\
         [[objects]]\nname = \"outer\"\nmesh = \"cube.obj\"\ngroup = \"outer\"\nmaterial = \"wall\"\n\n\
         [[objects]]\nname = \"inner\"\nmesh = \"cube.obj\"\ngroup = \"inner\"\nmaterial = \"white\"\n"
    );
    std::fs::write(dir.path().join("scene.toml"), toml).unwrap();
    let scene = load(&dir.path().join("scene.toml"));
    let outer = &scene.objects[0].mesh;
    let mut s = Simplified::from_triangles(
        &scene,
        outer
            .triangles
            .iter()
            .map(|t| (0, t.map(|v| outer.positions[v as usize]))),
    );
    s.pruned = (0..scene.objects[1].mesh.triangles.len() as u32)
        .map(|t| (1, t))
        .collect();
    let e = engine(&scene, 0.0);
    let sol = solve(&scene, &s, e.as_ref(), 0.0, Quality::new(0.5).unwrap())
        .unwrap_or_else(|e| panic!("{e:#}"));
    // Uniform radiosity `π(1 + ρ H/π)`: each record's indirect irradiance
    // is `πρ/(1 − ρ)`. The inner cube returns 98% of the uniform field over
    // at most a fifth of a record's view, which lowers it by under 1%.
    let want = PI * rho / (1.0 - rho);
    let worst = sol
        .indirect
        .iter()
        .zip(&s.records)
        .filter(|(_, r)| r.normal.dot(Vec3::splat(0.5) - r.position) > 0.0)
        .map(|(v, _)| (v.x / want - 1.0).abs())
        .fold(0.0f32, f32::max);
    println!("worst relative error {worst:.4}, {:?}", sol.stats);
    // The goal of the furnace with an occluder, below.
    assert!(worst < 0.07, "worst relative error {worst}");
}

#[test]
fn furnace_with_an_occluder_stays_uniform() {
    let dir = tempfile::tempdir().unwrap();
    let mut errors = Vec::new();
    for standing in [false, true] {
        let obj = furnace_with_inner_cube(standing);
        std::fs::write(dir.path().join("cube.obj"), &obj).unwrap();
        let rho = 0.5;
        let toml = format!(
            "[[materials]]\nname = \"wall\"\ntype = \"diffuse\"\nreflectance = [{rho}, {rho}, {rho}]\n\
             emission = [1, 1, 1]\ntwo_sided_emission = true\n\n\
             [[objects]]\nname = \"outer\"\nmesh = \"cube.obj\"\ngroup = \"outer\"\nmaterial = \"wall\"\n\n\
             [[objects]]\nname = \"inner\"\nmesh = \"cube.obj\"\ngroup = \"inner\"\nmaterial = \"wall\"\n"
        );
        std::fs::write(dir.path().join("scene.toml"), toml).unwrap();
        let scene = load(&dir.path().join("scene.toml"));
        let sol = run(&scene, 0.5);
        let want = PI * rho / (1.0 - rho);
        let lit = facing_in(&scene);
        let worst = sol
            .indirect
            .iter()
            .zip(lit)
            .filter_map(|(v, lit)| lit.then_some(v))
            .map(|v| (v.x / want - 1.0).abs())
            .fold(0.0f32, f32::max);
        println!(
            "standing {standing}: worst relative error {worst:.4}, {:?}",
            sol.stats
        );
        errors.push((standing, worst));
    }
    // The worst records are the outer cube's corners (3.4% and 6.4% low
    // measured), where corner elements gather through cluster links.
    for (standing, worst) in errors {
        assert!(
            worst < 0.07,
            "standing {standing}: worst relative error {worst}"
        );
    }
}

/// A finely tessellated ball in the Cornell box, coarsened by the
/// simplification: its patches are chords inside the real ball, which the
/// solver's shadow rays meet. Unless the patches are moved onto the true
/// surface (`standin`), every ray from them is blocked and the ball's
/// records come out black. Held to the same goal as the box's records.
#[test]
fn coarsened_ball_receives_its_light() {
    let dir = tempfile::tempdir().unwrap();
    let src = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box");
    let mut obj = std::fs::read_to_string(src.join("cornell-box.obj")).unwrap();
    let base = obj.lines().filter(|l| l.starts_with("v ")).count();
    let (centre, radius, rings, segments) = (Vec3::new(420.0, 70.0, 140.0), 70.0f32, 24, 48);
    obj.push_str("\no ball\n");
    for i in 0..=rings {
        let theta = PI * i as f32 / rings as f32;
        for j in 0..segments {
            let phi = 2.0 * PI * j as f32 / segments as f32;
            let v = centre
                + radius
                    * Vec3::new(
                        theta.sin() * phi.cos(),
                        theta.cos(),
                        theta.sin() * phi.sin(),
                    );
            obj.push_str(&format!("v {} {} {}\n", v.x, v.y, v.z));
        }
    }
    let at = |i: usize, j: usize| base + 1 + i * segments + j % segments;
    for i in 0..rings {
        for j in 0..segments {
            // Outward winding.
            obj.push_str(&format!(
                "f {} {} {} {}\n",
                at(i, j),
                at(i, j + 1),
                at(i + 1, j + 1),
                at(i + 1, j)
            ));
        }
    }
    std::fs::write(dir.path().join("cornell-box.obj"), obj).unwrap();
    let toml = std::fs::read_to_string(src.join("scene.toml")).unwrap()
        + "\n[[objects]]\nname = \"ball\"\nmesh = \"cornell-box.obj\"\ngroup = \"ball\"\nmaterial = \"white\"\n";
    std::fs::write(dir.path().join("scene.toml"), toml).unwrap();
    let scene = load(&dir.path().join("scene.toml"));
    let ball = scene.objects.iter().position(|o| o.name == "ball").unwrap();
    let quality = Quality::new(0.6).unwrap();
    let mut e = engine(&scene, 0.0);
    let report =
        rangewalk::radiosity::simplify::simplify_report(&scene, e.as_mut(), quality).unwrap();
    assert_eq!(
        report.objects[ball].fate,
        rangewalk::radiosity::simplify::Fate::Coarsened
    );
    let s = report.simplified;
    let sol = solve(&scene, &s, e.as_ref(), 0.0, quality).unwrap();
    // Every record on the ball's outer side away from the pole (where all
    // of a ring's triangles meet); each holds its patch's average, so the
    // goal applies to their mean.
    let (mut hr, mut mc, mut var, mut n) = (0.0, 0.0, 0.0, 0);
    for (r, rec) in s.records.iter().enumerate() {
        let outward = (rec.position - centre).normalize();
        if rec.object != ball as u32
            || rec.normal.dot(outward) < 0.8
            || !(-0.9..0.9).contains(&outward.y)
        {
            continue;
        }
        let x = rec.position + outward * 0.05;
        let (m, sigma) = monte_carlo_indirect_with_error(&scene, e.as_ref(), x, rec.normal, 10_000);
        hr += sol.indirect[r].element_sum();
        mc += m.element_sum();
        var += sigma * sigma;
        n += 1;
    }
    let (hr, mc, sigma) = (hr / n as f32, mc / n as f32, var.sqrt() / n as f32);
    println!("{n} records on the ball: radiosity {hr:.4}, Monte Carlo {mc:.4} ± {sigma:.4}");
    assert!(n >= 8, "{n} records on the ball");
    assert!(
        (hr - mc).abs() <= 0.1 * mc + 3.0 * sigma,
        "ball: radiosity {hr} vs Monte Carlo {mc} ± {sigma}"
    );
}

/// A stiff system without the furnace's symmetry: the Cornell box with its
/// white surfaces at reflectance 0.99, where light bounces dozens of times
/// before leaving through the open front. The linear solver must still
/// reach its tolerance (without restarts, BiCGSTAB once stalled at a
/// relative residual of 0.66 on the Cornell box cut into 12,640 patches),
/// and brighter walls can only add indirect light.
#[test]
fn stiff_cornell_box_converges() {
    let dir = tempfile::tempdir().unwrap();
    let src = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box");
    std::fs::copy(
        src.join("cornell-box.obj"),
        dir.path().join("cornell-box.obj"),
    )
    .unwrap();
    let toml = std::fs::read_to_string(src.join("scene.toml"))
        .unwrap()
        .replace("[0.725, 0.71, 0.68]", "[0.99, 0.99, 0.99]");
    std::fs::write(dir.path().join("scene.toml"), toml).unwrap();
    let stiff = load(&dir.path().join("scene.toml"));
    let plain = bundled("cornell-box");
    let (a, b) = (run(&plain, 0.6), run(&stiff, 0.6));
    println!(
        "rho 0.725: {} iterations, residual {:.2e}; rho 0.99: {} iterations, residual {:.2e}",
        a.stats.iterations, a.stats.residual, b.stats.iterations, b.stats.residual
    );
    assert_finite(&b);
    // What docs/radiosity.md claims: the solver's own tolerance, 1e-5.
    assert!(b.stats.residual < 1e-5, "residual {}", b.stats.residual);
    let mean = |s: &IndirectSolution| s.indirect.iter().map(|v| v.y).sum::<f32>();
    assert!(
        mean(&b) > 1.5 * mean(&a),
        "white at 0.99 gives {} against {}",
        mean(&b),
        mean(&a)
    );
}

/// `nu × nv` quads over the parallelogram from `o` along `u` and `v`, as
/// two triangles each (OBJ faces numbered from `first`).
fn grid_obj(o: Vec3, u: Vec3, v: Vec3, nu: usize, nv: usize, first: &mut usize) -> String {
    let mut obj = String::new();
    for i in 0..nu {
        for j in 0..nv {
            let at =
                |a: usize, b: usize| o + u * (a as f32 / nu as f32) + v * (b as f32 / nv as f32);
            for p in [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)] {
                obj.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
            }
            let n = *first;
            obj.push_str(&format!(
                "f {} {} {}\nf {} {} {}\n",
                n + 1,
                n + 2,
                n + 3,
                n + 1,
                n + 3,
                n + 4
            ));
            *first += 4;
        }
    }
    obj
}

/// A furnace the shape of a room: 6 × 3 × 4 m, tessellated at 0.5 m, so
/// that the solver clusters its patches and links clusters far apart (the
/// unit cube's twelve triangles are all close to one another and every link
/// ends on a surface). Every face reflects `rho` and emits on both sides.
fn furnace_room(dir: &Path, rho: f32) -> Scene {
    let (x, y, z) = (6.0, 3.0, 4.0);
    let (ex, ey, ez) = (Vec3::X * x, Vec3::Y * y, Vec3::Z * z);
    let mut n = 0;
    let obj = [
        grid_obj(Vec3::ZERO, ez, ex, 8, 12, &mut n),
        grid_obj(ey, ex, ez, 12, 8, &mut n),
        grid_obj(Vec3::ZERO, ex, ey, 12, 6, &mut n),
        grid_obj(ez, ey, ex, 6, 12, &mut n),
        grid_obj(Vec3::ZERO, ey, ez, 6, 8, &mut n),
        grid_obj(ex, ez, ey, 8, 6, &mut n),
    ]
    .concat();
    std::fs::write(dir.join("room.obj"), obj).unwrap();
    let toml = format!(
        "[[materials]]\nname = \"wall\"\ntype = \"diffuse\"\nreflectance = [{rho}, {rho}, {rho}]\n\
         emission = [1, 1, 1]\ntwo_sided_emission = true\n\n\
         [[objects]]\nname = \"room\"\nmesh = \"room.obj\"\nmaterial = \"wall\"\n"
    );
    std::fs::write(dir.join("scene.toml"), toml).unwrap();
    load(&dir.join("scene.toml"))
}

/// Links with a cluster end once carried the point kernel between the
/// ends' centres, which errs one way for ends as large as their distance:
/// every surface of this room gathered about 3% too much, and its records
/// came out 7% (ρ = 0.5) to 16% (ρ = 0.85) bright at q = 0.3. The closed
/// form is exact, so the bound is the goal alone: issue 47's 2% on the
/// mean, at every quality.
#[test]
fn a_tessellated_room_furnace_matches_the_closed_form() {
    let dir = tempfile::tempdir().unwrap();
    let centre = Vec3::new(3.0, 1.5, 2.0);
    for q in [0.3f32, 0.6, 0.9] {
        for rho in [0.5f32, 0.85] {
            let scene = furnace_room(dir.path(), rho);
            let s = Simplified::whole(&scene);
            let sol = run(&scene, q);
            let want = PI * rho / (1.0 - rho);
            let inside: Vec<f32> = s
                .records
                .iter()
                .zip(&sol.indirect)
                .filter(|(r, _)| r.normal.dot(centre - r.position) > 0.0)
                .map(|(_, v)| v.x / want - 1.0)
                .collect();
            let mean = inside.iter().sum::<f32>() / inside.len() as f32;
            let (lo, hi) = inside
                .iter()
                .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
            println!(
                "room furnace q = {q}, rho = {rho}: mean {:+.2}%, worst {:+.2}% / {:+.2}%, {} links",
                100.0 * mean, 100.0 * lo, 100.0 * hi, sol.stats.links
            );
            assert!(
                mean.abs() <= 0.02,
                "q = {q}, rho = {rho}: the inside records' mean is {:+.2}% off the closed form",
                100.0 * mean
            );
        }
    }
}
