//! The irradiance cache's interpolation truths and the multipass renderer
//! against the path tracer; `with_solver` checks radiosity indirect light
//! against path-traced indirect light.

use std::path::PathBuf;

use glam::Vec3;
use rangewalk::accel::{self, Backend};
use rangewalk::camera::Camera;
use rangewalk::image::{RangeImage, NO_HIT};
use rangewalk::radiosity::lookup::IrradianceCache;
use rangewalk::radiosity::{diffuse_albedo, Patch, RecordPoint, Simplified};
use rangewalk::render::{self, multipass, RenderSettings, RenderStats};
use rangewalk::scene::{Light, Scene};

mod common;
use common::load;

fn settings(spp: u32, max_depth: Option<u32>, seed: u64) -> RenderSettings {
    RenderSettings {
        spp,
        max_depth,
        seed,
    }
}

fn camera(scene: &Scene, size: u32) -> Camera {
    scene
        .camera("main")
        .unwrap()
        .perspective(size, size)
        .unwrap()
}

fn path_trace(scene: &Scene, cam: &Camera, t: f32, s: RenderSettings) -> RangeImage {
    let engine = accel::build(Backend::Bvh, &scene.geometry(), &scene.at(t)).unwrap();
    render::render(scene, engine.as_ref(), cam, t, &s)
        .unwrap()
        .0
}

fn multipass(
    scene: &Scene,
    cam: &Camera,
    t: f32,
    s: RenderSettings,
    cache: &IrradianceCache,
) -> (RangeImage, RenderStats) {
    let engine = accel::build(Backend::Bvh, &scene.geometry(), &scene.at(t)).unwrap();
    multipass::render(scene, engine.as_ref(), cam, t, &s, cache).unwrap()
}

fn uniform_cache(scene: &Scene, e: Vec3) -> (Simplified, IrradianceCache) {
    let s = Simplified::whole(scene);
    let cache = IrradianceCache::new(&s, &vec![e; s.records.len()]).unwrap();
    (s, cache)
}

fn mean(img: &RangeImage) -> Vec3 {
    img.radiance.iter().sum::<Vec3>() / img.len() as f32
}

fn luminance(v: Vec3) -> f64 {
    0.2126 * v.x as f64 + 0.7152 * v.y as f64 + 0.0722 * v.z as f64
}

/// RMS of the luminance difference over the mean reference luminance.
fn relative_lrms(test: &[Vec3], reference: &[Vec3]) -> f64 {
    let n = reference.len() as f64;
    let sq: f64 = test
        .iter()
        .zip(reference)
        .map(|(&a, &b)| (luminance(a) - luminance(b)).powi(2))
        .sum();
    let m: f64 = reference.iter().map(|&b| luminance(b)).sum::<f64>() / n;
    (sq / n).sqrt() / m
}

mod lookup {
    use super::*;

    /// A square grid of `n x n` cells of side `h` in the plane z = 0 of
    /// object 0, records at the grid points with `value(position)`.
    fn grid(n: usize, h: f32, value: impl Fn(Vec3) -> Vec3) -> (Simplified, Vec<Vec3>) {
        let mut records = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                records.push(RecordPoint {
                    object: 0,
                    position: Vec3::new(i as f32 * h, j as f32 * h, 0.0),
                    normal: Vec3::Z,
                });
            }
        }
        let id = |i: usize, j: usize| (j * (n + 1) + i) as u32;
        let mut patches = Vec::new();
        for j in 0..n {
            for i in 0..n {
                for c in [
                    [id(i, j), id(i + 1, j), id(i + 1, j + 1)],
                    [id(i, j), id(i + 1, j + 1), id(i, j + 1)],
                ] {
                    patches.push(Patch {
                        object: 0,
                        vertices: c.map(|k| records[k as usize].position),
                        corners: c,
                        back: c,
                        reflectance: Vec3::splat(0.5),
                        emission: Vec3::ZERO,
                        two_sided: false,
                    });
                }
            }
        }
        let values = records.iter().map(|r| value(r.position)).collect();
        let s = Simplified {
            patches,
            records,
            pruned: Vec::new(),
            stats: Default::default(),
        };
        (s, values)
    }

    /// Deterministic points in `[0, 1)²`.
    fn points(n: usize) -> impl Iterator<Item = (f32, f32)> {
        (0..n).map(|k| {
            let x = (k as f32 * 0.618_034).fract();
            let y = (k as f32 * 0.754_877 + 0.1).fract();
            (x, y)
        })
    }

    #[test]
    fn record_points_give_their_own_values_exactly() {
        let (s, values) = grid(6, 0.5, |p| {
            Vec3::new((p.x * 7.0).sin().abs(), p.y * p.y, 1e3 + p.x)
        });
        let cache = IrradianceCache::new(&s, &values).unwrap();
        for (r, &v) in s.records.iter().zip(&values) {
            assert_eq!(cache.irradiance(0, true, r.position, r.normal), v);
        }
    }

    #[test]
    fn linear_field_on_a_plane_is_reproduced() {
        for scale in [1.0f32, 1e4, 1e-4] {
            let f = |p: Vec3| {
                let q = p / scale;
                Vec3::new(2.0 + q.x, 1.0 + 0.5 * q.y, 3.0 + 0.2 * q.x - 0.3 * q.y)
            };
            let (s, values) = grid(5, 0.8 * scale, f);
            let cache = IrradianceCache::new(&s, &values).unwrap();
            for (x, y) in points(200) {
                let p = Vec3::new(x * 4.0 * scale, y * 4.0 * scale, 0.0);
                let got = cache.irradiance(0, true, p, Vec3::Z);
                let want = f(p);
                assert!(
                    ((got - want) / want).abs().max_element() < 1e-4,
                    "scale {scale}, at {p}: {got}, expected {want}"
                );
            }
        }
    }

    /// An L of a floor (normal +z) and a wall (normal +x) meeting at
    /// x = 0: points on the floor next to the crease see floor records only.
    #[test]
    fn no_light_leaks_across_a_crease() {
        let (mut s, mut values) = grid(4, 0.25, |_| Vec3::ONE);
        let floor = s.records.len();
        let wall: Vec<RecordPoint> = s
            .records
            .iter()
            .map(|r| RecordPoint {
                object: 0,
                position: Vec3::new(0.0, r.position.y, r.position.x),
                normal: Vec3::X,
            })
            .collect();
        let wall_patches: Vec<Patch> = s
            .patches
            .iter()
            .map(|p| Patch {
                vertices: p.vertices.map(|v| Vec3::new(0.0, v.y, v.x)),
                corners: p.corners.map(|c| c + floor as u32),
                back: p.back.map(|c| c + floor as u32),
                ..*p
            })
            .collect();
        s.records.extend(wall);
        s.patches.extend(wall_patches);
        values.extend(vec![Vec3::splat(100.0); floor]);
        let cache = IrradianceCache::new(&s, &values).unwrap();
        for (x, y) in points(100) {
            let on_floor = cache.irradiance(0, true, Vec3::new(0.05 * x, y, 0.0), Vec3::Z);
            let near = |a: Vec3, b: Vec3| ((a - b) / b).abs().max_element() < 1e-6;
            assert!(
                near(on_floor, Vec3::ONE),
                "floor at x = {}: {on_floor}",
                0.05 * x
            );
            let on_wall = cache.irradiance(0, true, Vec3::new(0.0, y, 0.05 * x), Vec3::X);
            assert!(near(on_wall, Vec3::splat(100.0)), "{on_wall}");
        }
        // A normal half way between the faces is 45° from both: neither
        // face's records apply, and the nearest-record fallback gives a
        // value between them.
        let mid = cache.irradiance(0, true, Vec3::ZERO, Vec3::new(1.0, 0.0, 1.0).normalize());
        assert!(
            mid.min_element() >= 1.0 && mid.max_element() <= 100.0,
            "{mid}"
        );
    }

    #[test]
    fn missing_records_fall_back_to_the_scene_average() {
        let (s, values) = grid(2, 1.0, |p| Vec3::splat(1.0 + p.x));
        let cache = IrradianceCache::new(&s, &values).unwrap();
        // Area-weighted mean of a linear field over the square: its centre.
        assert!((cache.average() - Vec3::splat(2.0)).length() < 1e-5);
        assert_eq!(
            cache.irradiance(7, true, Vec3::ZERO, Vec3::Z),
            cache.average()
        );
        // Facing away from every record.
        assert_eq!(
            cache.irradiance(0, true, Vec3::ONE, -Vec3::Z),
            cache.average()
        );
        // Out of every record's range on the plane: the nearest records
        // (value 3 at x = 2), not the average.
        let far = cache.irradiance(0, true, Vec3::new(4.5, 1.0, 0.0), Vec3::Z);
        assert!(far.x > 2.8 && far.x <= 3.0, "{far}");
    }

    #[test]
    fn degenerate_inputs_give_finite_values() {
        let (mut s, mut values) = grid(2, 1.0, |_| Vec3::ONE);
        s.records[0].normal = Vec3::ZERO;
        s.records[1].position = Vec3::NAN;
        s.patches[0].vertices = [Vec3::ZERO; 3];
        values[2] = Vec3::INFINITY;
        values[3] = Vec3::splat(f32::NAN);
        values[4] = Vec3::splat(-1.0);
        let cache = IrradianceCache::new(&s, &values).unwrap();
        for p in [Vec3::ZERO, Vec3::ONE, Vec3::NAN, Vec3::splat(1e30), Vec3::X] {
            for n in [Vec3::Z, Vec3::ZERO, Vec3::NAN, -Vec3::Z, Vec3::splat(1e-30)] {
                for object in [0, 1, u32::MAX] {
                    let e = cache.irradiance(object, true, p, n);
                    assert!(e.is_finite() && e.min_element() >= 0.0, "{p} {n}: {e}");
                }
            }
        }
        let empty = IrradianceCache::new(&Simplified::default(), &[]).unwrap();
        assert_eq!(empty.irradiance(0, true, Vec3::ZERO, Vec3::Z), Vec3::ZERO);
        // Values for another set of records are refused, naming both counts.
        let e = IrradianceCache::new(&s, &values[..3])
            .err()
            .expect("3 values accepted");
        let n = s.records.len();
        assert!(
            format!("{e}").contains(&format!("3 irradiance values for {n} records")),
            "{e}"
        );
        let mut long = values.clone();
        long.push(Vec3::ONE);
        assert!(IrradianceCache::new(&s, &long).is_err());
    }
}

/// Each side of a surface is looked up in its own records, which sit at the
/// same points as the other side's: the Cornell box's floor with 1 on its
/// front records and 5 on its back ones gives 1 and 5, never a blend; and
/// the scene average that stands in for missing records leaves the unlit
/// (zero) sides out.
#[test]
fn each_side_is_looked_up_in_its_own_records() {
    let scene = load("cornell-box");
    let s = Simplified::whole(&scene);
    let mut values = vec![Vec3::ZERO; s.records.len()];
    for p in s.patches.iter().filter(|p| p.object == 0) {
        for k in 0..3 {
            values[p.corners[k] as usize] = Vec3::ONE;
            values[p.back[k] as usize] = Vec3::splat(5.0);
        }
    }
    let cache = IrradianceCache::new(&s, &values).unwrap();
    let floor = s.patches.iter().find(|p| p.object == 0).unwrap();
    let n = floor.normal();
    let centre = (floor.vertices[0] + floor.vertices[1] + floor.vertices[2]) / 3.0;
    let close = |a: Vec3, b: Vec3| (a - b).abs().max_element() < 1e-5;
    assert!(close(cache.irradiance(0, true, centre, n), Vec3::ONE));
    assert!(close(
        cache.irradiance(0, false, centre, -n),
        Vec3::splat(5.0)
    ));
    // The average is over the floor's two sides alone, equal in area.
    assert!((cache.average() - Vec3::splat(3.0)).abs().max_element() < 1e-4);
}

/// With nothing in the cache, multipass is direct light only: the path
/// tracer's `max_depth = 2` image, within noise.
#[test]
fn zero_cache_equals_direct_only_path_tracing() {
    for (name, t) in [("cornell-box", 0.5), ("glossy-sun", 1.0)] {
        let scene = load(name);
        let cam = camera(&scene, 24);
        let (_, cache) = uniform_cache(&scene, Vec3::ZERO);
        let reference = path_trace(&scene, &cam, t, settings(256, Some(2), 1));
        let (img, _) = multipass(&scene, &cam, t, settings(256, Some(2), 2), &cache);
        let (a, b) = (mean(&img), mean(&reference));
        assert!(
            ((a - b) / b).abs().max_element() < 0.03,
            "{name}: multipass mean {a}, path tracer {b}"
        );
        // Per pixel: the difference is noise only. Against another run of
        // the path tracer it is sqrt(2) σ; against multipass with noise kσ
        // it is sqrt(1 + k²) σ. Allow multipass twice the noise (k = 2).
        let lrms = relative_lrms(&img.radiance, &reference.radiance);
        let again = path_trace(&scene, &cam, t, settings(256, Some(2), 3));
        let floor = relative_lrms(&again.radiance, &reference.radiance);
        eprintln!("{name}: mean {a} vs {b}; relative LRMS {lrms:.3}, path tracer against itself {floor:.3}");
        assert!(
            lrms < (2.5f64).sqrt() * floor,
            "{name}: relative LRMS {lrms}, path tracer against itself {floor}"
        );
        // The same first hits as the path tracer.
        assert_eq!(img.object_id, reference.object_id);
        assert_eq!(img.distance, reference.distance);
        assert_eq!(img.normal, reference.normal);
    }
}

/// Unlit, under a uniform irradiance E, a diffuse surface of albedo ρ
/// leaves ρ E / π, whatever E's magnitude.
#[test]
fn uniform_irradiance_adds_albedo_times_e_over_pi() {
    let mut scene = load("cornell-box");
    for m in &mut scene.materials {
        m.emission = None;
    }
    let cam = camera(&scene, 20);
    for e in [1e-6f32, 1.0, 1e8] {
        let (_, cache) = uniform_cache(&scene, Vec3::splat(e));
        let (img, _) = multipass(&scene, &cam, 0.3, settings(2, None, 3), &cache);
        let rho = |k: u32| diffuse_albedo(&scene.material_of(k).bsdf);
        let hi = (0..scene.objects.len() as u32)
            .map(rho)
            .fold(Vec3::ZERO, Vec3::max);
        let mut exact = 0;
        for (k, (&l, &id)) in img.radiance.iter().zip(&img.object_id).enumerate() {
            assert!(l.is_finite(), "pixel {k}: {l}");
            if id == NO_HIT {
                continue;
            }
            let want = rho(id) * e / std::f32::consts::PI;
            if ((l - want) / want).abs().max_element() < 1e-5 {
                exact += 1;
            }
            // Pixels on an edge mix objects (and the background).
            let (a, b) = (Vec3::ZERO, hi * e / 3.1);
            assert!(l.cmpge(a).all() && l.cmple(b).all(), "pixel {k}: {l}");
        }
        assert!(exact * 10 >= img.len() * 8, "e = {e}: {exact} exact pixels");
    }
}

/// Only camera and shadow rays in a scene without glossy or mirror
/// surfaces.
#[test]
fn diffuse_scene_traces_no_reflection_rays() {
    let scene = load("cornell-box");
    assert!(!scene.has_specular());
    let cam = camera(&scene, 16);
    let (_, cache) = uniform_cache(&scene, Vec3::ONE);
    let spp = 4;
    let (_, stats) = multipass(&scene, &cam, 0.0, settings(spp, None, 0), &cache);
    let pixels = cam.width as u64 * cam.height as u64;
    assert!(
        stats.rays <= pixels * (1 + 2 * spp as u64),
        "{} rays",
        stats.rays
    );
    // With glossy and mirror surfaces, reflections are traced.
    let glossy = load("glossy-sun");
    let (_, cache) = uniform_cache(&glossy, Vec3::ONE);
    let cam = camera(&glossy, 16);
    let (_, stats) = multipass(&glossy, &cam, 0.0, settings(spp, None, 0), &cache);
    assert!(
        stats.rays > pixels * (1 + 2 * spp as u64),
        "{} rays",
        stats.rays
    );
}

#[test]
fn same_seed_same_image_on_any_thread_count() {
    let scene = load("glossy-sun");
    let cam = camera(&scene, 20);
    let (_, cache) = uniform_cache(&scene, Vec3::splat(0.3));
    let s = settings(3, None, 9);
    let (a, _) = multipass(&scene, &cam, 0.5, s, &cache);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let (b, _) = pool.install(|| multipass(&scene, &cam, 0.5, s, &cache));
    assert_eq!(a.radiance, b.radiance);
}

/// Light intensities over 14 orders of magnitude: finite, and linear.
#[test]
fn extreme_intensities_stay_finite_and_linear() {
    let base = load("glossy-sun");
    let cam = camera(&base, 12);
    let s = settings(2, None, 4);
    let mut means = Vec::new();
    for k in [1e-6f32, 1.0, 1e8] {
        let mut scene = base.clone();
        for l in &mut scene.lights {
            match l {
                Light::Point { intensity, .. } => *intensity *= k,
                Light::Sun { radiance, .. } => *radiance *= k,
            }
        }
        let (_, cache) = uniform_cache(&scene, Vec3::splat(k));
        let (img, _) = multipass(&scene, &cam, 0.0, s, &cache);
        assert!(img.radiance.iter().all(|l| l.is_finite()));
        means.push(mean(&img) / k);
    }
    for m in &means[1..] {
        assert!(
            ((*m - means[0]) / means[0]).abs().max_element() < 1e-3,
            "{means:?}"
        );
    }
}

/// Every triangle of `scene` split in four until no edge exceeds
/// `max_edge`: records on a grid fine enough for indirect light to vary
/// between them.
fn subdivided(scene: &Scene, max_edge: f32) -> Simplified {
    fn split(t: [Vec3; 3], max_edge: f32, out: &mut Vec<[Vec3; 3]>) {
        let [a, b, c] = t;
        let longest = (b - a).length().max((c - b).length()).max((a - c).length());
        if longest <= max_edge {
            out.push(t);
            return;
        }
        let (ab, bc, ca) = ((a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5);
        for t in [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]] {
            split(t, max_edge, out);
        }
    }
    let mut triangles = Vec::new();
    for (k, o) in scene.objects.iter().enumerate() {
        for t in &o.mesh.triangles {
            let mut out = Vec::new();
            split(t.map(|v| o.mesh.positions[v as usize]), max_edge, &mut out);
            triangles.extend(out.into_iter().map(|t| (k as u32, t)));
        }
    }
    Simplified::from_triangles(scene, triangles)
}

/// Indirect irradiance at every record by path tracing: incoming radiance
/// over the full sphere (equal-area pixels) at the record, minus what
/// emitters send directly, cosine-weighted.
fn gathered_indirect(scene: &Scene, s: &Simplified, t: f32) -> Vec<Vec3> {
    use rangewalk::camera::Projection;
    let engine = accel::build(Backend::Bvh, &scene.geometry(), &scene.at(t)).unwrap();
    let poses = scene.at(t);
    let size = scene.bounds(t);
    let eps = 1e-3 * (size.1 - size.0).max_element();
    // Where each record's patches lie: gathering points are nudged
    // towards them, off creases.
    let mut centre = vec![(Vec3::ZERO, 0.0f32); s.records.len()];
    for p in &s.patches {
        let c = (p.vertices[0] + p.vertices[1] + p.vertices[2]) / 3.0;
        for &k in p.corners.iter().chain(&p.back) {
            centre[k as usize].0 += c;
            centre[k as usize].1 += 1.0;
        }
    }
    s.records
        .iter()
        .zip(&centre)
        .map(|(r, &(c, count))| {
            let pose = poses[r.object as usize];
            let n = pose.transform_vector3(r.normal).normalize();
            let p = pose.transform_point3(r.position + (c / count - r.position) * 0.02) + n * eps;
            let up = if n.y.abs() < 0.9 { Vec3::Y } else { Vec3::X };
            let cam = Camera::looking(p, n, up, Projection::Sphere, 16, 16).unwrap();
            let full = render::render(scene, engine.as_ref(), &cam, t, &settings(8, None, 11));
            let seen = render::render(scene, engine.as_ref(), &cam, t, &settings(8, Some(1), 11));
            let (full, seen) = (full.unwrap().0, seen.unwrap().0);
            let mut e = Vec3::ZERO;
            for j in 0..16 {
                for i in 0..16 {
                    let k = (j * 16 + i) as usize;
                    let dir = cam.ray(i as f32 + 0.5, j as f32 + 0.5).unwrap().dir;
                    let cos = dir.dot(n).max(0.0);
                    e += (full.radiance[k] - seen.radiance[k]).max(Vec3::ZERO)
                        * cos
                        * cam.pixel_solid_angle(i, j);
                }
            }
            e
        })
        .collect()
}

/// Path-traced indirect light: the full image minus the direct-only one,
/// with the same random numbers, so that emitters seen directly and direct
/// light cancel exactly.
fn path_traced_indirect(scene: &Scene, cam: &Camera, t: f32, spp: u32, seed: u64) -> Vec<Vec3> {
    let full = path_trace(scene, cam, t, settings(spp, None, seed));
    let direct = path_trace(scene, cam, t, settings(spp, Some(2), seed));
    full.radiance
        .iter()
        .zip(&direct.radiance)
        .map(|(a, b)| *a - *b)
        .collect()
}

/// Multipass indirect light: with the records minus with none (the same
/// random numbers, so direct light cancels exactly).
fn multipass_indirect(
    scene: &Scene,
    cam: &Camera,
    t: f32,
    s: &Simplified,
    e: &[Vec3],
) -> Vec<Vec3> {
    let cache = IrradianceCache::new(s, e).unwrap();
    let none = IrradianceCache::new(s, &vec![Vec3::ZERO; s.records.len()]).unwrap();
    let st = settings(16, None, 5);
    let with = multipass(scene, cam, t, st, &cache).0;
    let without = multipass(scene, cam, t, st, &none).0;
    with.radiance
        .iter()
        .zip(&without.radiance)
        .map(|(a, b)| *a - *b)
        .collect()
}

fn compare_indirect(what: &str, ours: &[Vec3], reference: &[Vec3]) -> (f32, f64) {
    let n = reference.len() as f32;
    let (m_ours, m_ref) = (
        ours.iter().sum::<Vec3>() / n,
        reference.iter().sum::<Vec3>() / n,
    );
    let mean_error = ((m_ours - m_ref) / m_ref).abs().max_element();
    let lrms = relative_lrms(ours, reference);
    eprintln!(
        "{what}: mean {m_ours}, path tracer {m_ref} (relative error {mean_error:.3}); \
         relative LRMS {lrms:.3}"
    );
    (mean_error, lrms)
}

/// Records whose irradiance is gathered by path tracing, looked up by the
/// multipass renderer, give the path tracer's indirect light: the lookup
/// and the renderer's use of it are right, whatever the solver.
#[test]
fn gathered_records_give_path_traced_indirect_light() {
    let scene = load("cornell-box");
    let t = 0.0;
    let cam = camera(&scene, 24);
    let s = subdivided(&scene, 150.0);
    let e = gathered_indirect(&scene, &s, t);
    let ours = multipass_indirect(&scene, &cam, t, &s, &e);
    let reference = path_traced_indirect(&scene, &cam, t, 512, 6);
    // Measured: mean 0.019, LRMS 0.105, where two path-traced references
    // of different seeds differ by 0.003 and 0.117.
    let (mean_error, lrms) = compare_indirect("Cornell box, gathered records", &ours, &reference);
    assert!(mean_error < 0.05, "mean indirect off by {mean_error}");
    assert!(lrms < 0.2, "relative LRMS {lrms}");
}

/// The command line with a bake made by hand: `render --indirect
/// radiosity --bake` reuses it, and refuses one made for another quality.
mod cli {
    use super::*;
    use rangewalk::radiosity::store;
    use rangewalk::radiosity::temporal::TimeSeries;
    use rangewalk::radiosity::{IndirectSolution, SolveStats};
    use std::fs;
    use std::process::{Command, Output};

    pub fn rangewalk(args: &[&str]) -> Output {
        Command::new(env!("CARGO_BIN_EXE_rangewalk"))
            .args(args)
            .output()
            .expect("run rangewalk")
    }

    pub fn scene_path(name: &str) -> String {
        format!("{}/scenes/{name}/scene.toml", env!("CARGO_MANIFEST_DIR"))
    }

    #[test]
    fn render_uses_an_existing_bake() {
        let scene = load("cornell-box");
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("cb.bake");
        let s = Simplified::whole(&scene);
        let e = 1000.0;
        let solution = |time| IndirectSolution {
            time,
            indirect: vec![Vec3::splat(e); s.records.len()],
            direct: vec![Vec3::ZERO; s.records.len()],
            stats: SolveStats::default(),
        };
        let series = TimeSeries {
            times: vec![0.0, 1.0],
            solutions: vec![solution(0.0), solution(1.0)],
            quality: rangewalk::quality::Quality::DEFAULT,
            stats: Default::default(),
        };
        store::save(&dir, &scene, &s, &series).unwrap();
        let cb = scene_path("cornell-box");
        let out = tmp.path().join("mp.exr");
        let (d, o) = (dir.to_str().unwrap(), out.to_str().unwrap());
        let base = [
            "render",
            &cb,
            "--size",
            "8x8",
            "--spp",
            "2",
            "--out",
            o,
            "--backend",
            "bvh",
            "--indirect",
            "radiosity",
            "--bake",
            d,
        ];
        let r = rangewalk(&base);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        assert!(String::from_utf8_lossy(&r.stdout).contains("multipass"));
        // The bright uniform records show: hit pixels (but those partly
        // on the background) get at least ρ_min E / π (the red wall's blue
        // channel: 0.05 E / π).
        let img = rangewalk::image::read_exr(&out).unwrap();
        let hit: Vec<Vec3> = (img.radiance.iter().zip(&img.object_id))
            .filter(|(_, id)| **id != NO_HIT)
            .map(|(l, _)| *l)
            .collect();
        let bright = hit
            .iter()
            .filter(|l| l.min_element() > 0.04 * e / std::f32::consts::PI)
            .count();
        assert!(bright * 4 >= hit.len() * 3, "{bright} of {}", hit.len());

        let mut other = base.to_vec();
        other.extend(["--quality", "0.3"]);
        let r = rangewalk(&other);
        assert!(!r.status.success());
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(
            err.contains("quality 0.5") && err.contains("cb.bake"),
            "{err}"
        );

        // --bake and --quality belong to radiosity.
        let r = rangewalk(&["render", &cb, "--out", o, "--bake", d]);
        assert!(String::from_utf8_lossy(&r.stderr).contains("--indirect radiosity"));

        // The bake fits only the scene it was made for: not the same box
        // scaled (same triangle count), not a copy with a changed material.
        let refused = |scene: &str, what: &str| {
            let mut args = base.to_vec();
            args[1] = scene;
            let r = rangewalk(&args);
            let err = String::from_utf8_lossy(&r.stderr);
            assert!(!r.status.success(), "{scene}: bake accepted");
            assert!(
                err.contains("differs") && err.contains(what),
                "{scene}: {err}"
            );
        };
        refused(&scene_path("cornell-box-1e4"), "text");
        let copy = tmp.path().join("copy");
        fs::create_dir(&copy).unwrap();
        let src = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box");
        fs::copy(src.join("cornell-box.obj"), copy.join("cornell-box.obj")).unwrap();
        let text = fs::read_to_string(src.join("scene.toml")).unwrap();
        let edited = text.replacen("[0.63, 0.065, 0.05]", "[0.63, 0.065, 0.06]", 1);
        assert_ne!(edited, text);
        fs::write(copy.join("scene.toml"), edited).unwrap();
        refused(
            copy.join("scene.toml").to_str().unwrap(),
            "material `red` changed",
        );
    }
}

/// Radiosity indirect light against path-traced indirect light. Needs the
/// hierarchical radiosity solver.
mod with_solver {
    use super::*;
    use rangewalk::quality::Quality;
    use rangewalk::radiosity::solve;

    /// Cornell box, patches no larger than 150 mm: multipass indirect light
    /// from the solved records against the path tracer's.
    #[test]
    fn cornell_box_indirect_matches_path_tracing() {
        let scene = load("cornell-box");
        let t = 0.0;
        let cam = camera(&scene, 24);
        let engine = accel::build(Backend::Bvh, &scene.geometry(), &scene.at(t)).unwrap();
        let s = subdivided(&scene, 150.0);
        let q = Quality::new(0.8).unwrap();
        let solution = solve(&scene, &s, engine.as_ref(), t, q).unwrap();
        let ours = multipass_indirect(&scene, &cam, t, &s, &solution.indirect);
        let reference = path_traced_indirect(&scene, &cam, t, 512, 6);
        let (mean_error, lrms) =
            compare_indirect("Cornell box, radiosity records", &ours, &reference);
        assert!(mean_error < 0.1, "mean indirect off by {mean_error}");
        assert!(lrms < 0.35, "relative LRMS {lrms}");
    }

    /// The studio through the whole pipeline (simplification at q = 0.6,
    /// solve, records looked up by the multipass renderer) against the same
    /// renderer with one traced diffuse bounce in place of the records
    /// (`Indirect::Traced`, unbiased). Direct light, glossy and mirror
    /// reflections are the same in both images, so their means differ by
    /// the records' error as the camera sees it: sunlight off a glossy
    /// floor, furniture coarsened to stand-ins, chairs and tables in the
    /// way. The goal is the studio's (2% of the image at q = 0.6), plus
    /// three standard errors of the difference (each image rendered with
    /// two seeds). The looked-up light was 9% low (4.3% of the image)
    /// before the fixes in docs/radiosity.md ("The dark bias").
    #[test]
    fn studio_records_agree_with_a_traced_bounce() {
        let scene = load("studio");
        let (engine, cache) = solved_at_start(&scene);
        let cam = camera(&scene, 32);
        let mean_and_error = |indirect: multipass::Indirect| {
            let [a, b] = [1, 2]
                .map(|seed| render_128_spp(&scene, engine.as_ref(), &cam, indirect, seed).radiance);
            mean_of_two(&a, &b, &vec![true; a.len()])
        };
        let (ours, e1) = mean_and_error(multipass::Indirect::Records(&cache));
        let (traced, e2) = mean_and_error(multipass::Indirect::Traced);
        let sigma = (e1 * e1 + e2 * e2).sqrt();
        println!(
            "studio at q = 0.6: records {ours:.5}, traced bounce {traced:.5} ± {sigma:.5} ({:+.4})",
            ours / traced - 1.0
        );
        assert!(
            (ours - traced).abs() <= 0.02 * traced + 3.0 * sigma,
            "records {ours} vs traced bounce {traced} ± {sigma}"
        );
    }

    /// A ray engine of `scene` posed at t = 0 and the records of its
    /// radiosity solved there at q = 0.6.
    fn solved_at_start(scene: &Scene) -> (Box<dyn accel::InstancedEngine>, IrradianceCache) {
        let q = Quality::new(0.6).unwrap();
        let mut engine = accel::build(
            Backend::default_available(),
            &scene.geometry(),
            &scene.at(0.0),
        )
        .unwrap();
        let s = rangewalk::radiosity::simplify(scene, engine.as_mut(), q).unwrap();
        let solution = solve(scene, &s, engine.as_ref(), 0.0, q).unwrap();
        let cache = IrradianceCache::new(&s, &solution.indirect).unwrap();
        (engine, cache)
    }

    /// The multipass render of `cam` at t = 0, 128 spp, with `seed`.
    fn render_128_spp(
        scene: &Scene,
        engine: &dyn rangewalk::accel::RayEngine,
        cam: &Camera,
        indirect: multipass::Indirect,
        seed: u64,
    ) -> RangeImage {
        multipass::render_layers(
            scene,
            engine,
            cam,
            0.0,
            &settings(128, None, seed),
            indirect,
            None,
            render::Progress::Tiles,
        )
        .unwrap()
        .image
    }

    /// The mean luminance over the pixels `mask` picks of two renders of
    /// one image with other seeds, `a` and `b`, and its standard error:
    /// Var(a_i - b_i) = 2 Var(a_i), so the variance of the two images'
    /// mean is Σ (a_i - b_i)² / 4 / n².
    fn mean_of_two(a: &[Vec3], b: &[Vec3], mask: &[bool]) -> (f64, f64) {
        let pairs: Vec<(f64, f64)> = a
            .iter()
            .zip(b)
            .zip(mask)
            .filter(|(_, &m)| m)
            .map(|((&x, &y), _)| (luminance(x), luminance(y)))
            .collect();
        let n = pairs.len() as f64;
        let mean = pairs.iter().map(|(x, y)| x + y).sum::<f64>() / (2.0 * n);
        let sq: f64 = pairs.iter().map(|(x, y)| (x - y).powi(2)).sum();
        (mean, sq.sqrt() / (2.0 * n))
    }

    /// Records hold each element's mean light, so where two walls meet
    /// they are brighter than the light there (5-15% in the Cornell box's
    /// corners at q = 0.6). Gathered through one traced bounce, the records
    /// at the bounce's far end are the walls' mean light too, but the
    /// corner's geometry (how much of each point's view the other wall
    /// takes, and at what angle) is traced, which is what darkens it. The
    /// gathered image agrees with the traced bounce (unbiased) over the
    /// whole image and over the pixels within 20 mm of two walls: within
    /// the records' goal (2% of the light, issue 47), plus three standard
    /// errors of the difference (each image rendered with two seeds).
    #[test]
    fn gathered_records_keep_the_darkening_where_walls_meet() {
        let scene = load("cornell-box");
        let (engine, cache) = solved_at_start(&scene);
        let cam = camera(&scene, 64);
        let (lo, hi) = scene.bounds(0.0);
        let render = |indirect: multipass::Indirect, seed: u64| {
            render_128_spp(&scene, engine.as_ref(), &cam, indirect, seed)
        };
        // Pixels whose first hit lies within 20 mm of two of the room's
        // five walls (the front is open).
        let first = render(multipass::Indirect::Traced, 1);
        let corner: Vec<bool> = (0..first.radiance.len())
            .map(|k| {
                let (x, y) = (k as u32 % cam.width, k as u32 / cam.width);
                let ray = cam.ray(x as f32 + 0.5, y as f32 + 0.5).unwrap();
                let d = first.distance[k];
                if first.object_id[k] == NO_HIT || !d.is_finite() {
                    return false;
                }
                let p = ray.origin + ray.dir.normalize() * d;
                let near = [p.x - lo.x, hi.x - p.x, p.y - lo.y, hi.y - p.y, hi.z - p.z];
                near.iter().filter(|&&n| n.abs() < 20.0).count() >= 2
            })
            .collect();
        let corners = corner.iter().filter(|&&c| c).count();
        assert!(corners > 100, "only {corners} corner pixels");
        let all = vec![true; corner.len()];
        let mean_and_error = |indirect: multipass::Indirect, mask: &[bool]| {
            let [a, b] = [1, 2].map(|seed| render(indirect, seed).radiance);
            mean_of_two(&a, &b, mask)
        };
        for (what, mask) in [("image", &all), ("corners", &corner)] {
            let (gathered, e1) = mean_and_error(multipass::Indirect::Gathered(&cache), mask);
            let (records, _) = mean_and_error(multipass::Indirect::Records(&cache), mask);
            let (traced, e2) = mean_and_error(multipass::Indirect::Traced, mask);
            let sigma = (e1 * e1 + e2 * e2).sqrt();
            println!(
                "Cornell box {what} at q = 0.6: gathered {:+.4}, records {:+.4} against a traced \
                 bounce {traced:.5} ± {sigma:.5}",
                gathered / traced - 1.0,
                records / traced - 1.0
            );
            assert!(
                (gathered - traced).abs() <= 0.02 * traced + 3.0 * sigma,
                "{what}: gathered {gathered} vs traced bounce {traced} ± {sigma}"
            );
        }
    }

    /// `rangewalk radiosity` on the animated Cornell box reports every
    /// stage and writes a bake that `render` then reuses.
    #[test]
    fn radiosity_command_bakes_and_render_reuses_it() {
        use super::cli::{rangewalk, scene_path};
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("cb.bake");
        let cb = scene_path("cornell-box");
        let d = dir.to_str().unwrap();
        let r = rangewalk(&[
            "radiosity",
            &cb,
            "--quality",
            "0.3",
            "--out",
            d,
            "--backend",
            "bvh",
        ]);
        let stdout = String::from_utf8_lossy(&r.stdout);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        for part in [
            "simplification:",
            "time list",
            "solve t = 0:",
            "temporal decomposition:",
        ] {
            assert!(stdout.contains(part), "no `{part}` in:\n{stdout}");
        }
        let (_, series) = rangewalk::radiosity::store::load(&dir).unwrap();
        assert_eq!(series.times.first(), Some(&0.0));
        assert_eq!(series.times.last(), Some(&1.0));
        let out = tmp.path().join("mp.exr");
        let r = rangewalk(&[
            "render",
            &cb,
            "--size",
            "8x8",
            "--spp",
            "2",
            "--out",
            out.to_str().unwrap(),
            "--backend",
            "bvh",
            "--indirect",
            "radiosity",
            "--quality",
            "0.3",
            "--bake",
            d,
            "--time",
            "0.4",
        ]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        assert!(String::from_utf8_lossy(&r.stderr).contains("using the bake"));
    }
}
