//! Ray throughput of every backend in the build, single-threaded, on a large
//! generated scene (over a million distinct triangles, instanced) and on a
//! Cornell-box-like room, for coherent primary rays, incoherent diffuse
//! bounces and shadow rays; plus build and transform-update times.
//!
//! All rays are generated once, with a fixed seed, outside the timed loops;
//! every backend traces the same rays.

use std::f32::consts::{PI, TAU};
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::{Affine3A, Quat, Vec3};
use rangewalk::accel::{self, offset_origin, Backend, InstancedEngine, MeshGeometry, Ray};
use rangewalk::camera::{Camera, Projection};

/// Pixels of the primary-ray image, and rays of the other kinds.
const WIDTH: u32 = 256;
const HEIGHT: u32 = 256;
const RAYS: usize = (WIDTH * HEIGHT) as usize;

/// SplitMix64: fixed-seed inputs without another dependency.
struct Rng(u64);

impl Rng {
    fn f32(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// A `(rows + 1) x (cols + 1)` vertex grid, two triangles per cell, with
/// positions from `f(row / rows, col / cols)`.
fn grid(rows: u32, cols: u32, f: impl Fn(f32, f32) -> Vec3) -> MeshGeometry {
    let mut mesh = MeshGeometry::default();
    for r in 0..=rows {
        for c in 0..=cols {
            mesh.positions
                .push(f(r as f32 / rows as f32, c as f32 / cols as f32));
        }
    }
    let at = |r: u32, c: u32| r * (cols + 1) + c;
    for r in 0..rows {
        for c in 0..cols {
            mesh.triangles
                .push([at(r, c), at(r + 1, c), at(r + 1, c + 1)]);
            mesh.triangles
                .push([at(r, c), at(r + 1, c + 1), at(r, c + 1)]);
        }
    }
    mesh
}

/// A unit sphere with a bumpy radius, about 520k triangles.
fn displaced_sphere() -> MeshGeometry {
    grid(360, 720, |s, t| {
        let (theta, phi) = (s * PI, t * TAU);
        let r = 1.0
            + 0.08 * (7.0 * theta).sin() * (5.0 * phi).cos()
            + 0.03 * (23.0 * theta + 3.0 * phi).sin();
        Vec3::new(
            r * theta.sin() * phi.cos(),
            r * theta.cos(),
            r * theta.sin() * phi.sin(),
        )
    })
}

/// Rolling terrain over `[-4, 4]^2`, about 520k triangles.
fn terrain() -> MeshGeometry {
    grid(511, 511, |s, t| {
        let (x, z) = (8.0 * s - 4.0, 8.0 * t - 4.0);
        let y = 0.3 * (1.3 * x).sin() * (1.7 * z).cos() + 0.05 * (5.0 * x + 3.0 * z).sin();
        Vec3::new(x, y, z)
    })
}

fn quad(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> MeshGeometry {
    MeshGeometry {
        positions: vec![a, b, c, d],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

fn unit_box() -> MeshGeometry {
    let positions = (0..8)
        .map(|c| {
            Vec3::new(
                (c & 1) as f32 - 0.5,
                ((c >> 1) & 1) as f32,
                ((c >> 2) & 1) as f32 - 0.5,
            )
        })
        .collect();
    let triangles = vec![
        [0, 2, 3],
        [0, 3, 1],
        [4, 5, 7],
        [4, 7, 6],
        [0, 1, 5],
        [0, 5, 4],
        [2, 6, 7],
        [2, 7, 3],
        [0, 4, 6],
        [0, 6, 2],
        [1, 3, 7],
        [1, 7, 5],
    ];
    MeshGeometry {
        positions,
        triangles,
    }
}

struct BenchScene {
    name: &'static str,
    meshes: Vec<MeshGeometry>,
    transforms: Vec<Affine3A>,
    camera: Camera,
    /// Shadow rays go to points of this parallelogram: corner, two edges.
    light: (Vec3, Vec3, Vec3),
}

/// Terrain plus three instances of the displaced sphere: 1.04M distinct
/// triangles, 2.08M instanced.
fn big_scene() -> BenchScene {
    let sphere = displaced_sphere();
    let meshes = vec![terrain(), sphere.clone(), sphere.clone(), sphere];
    let transforms = vec![
        Affine3A::from_translation(Vec3::new(0.0, -1.2, 0.0)),
        Affine3A::from_translation(Vec3::new(0.0, 0.0, 0.0)),
        Affine3A::from_scale_rotation_translation(
            Vec3::splat(0.6),
            Quat::from_rotation_y(0.7),
            Vec3::new(-2.0, -0.5, 1.0),
        ),
        Affine3A::from_scale_rotation_translation(
            Vec3::new(0.8, 1.2, 0.8),
            Quat::from_rotation_z(0.4),
            Vec3::new(2.2, -0.3, -1.0),
        ),
    ];
    let camera = Camera::look_at(
        Vec3::new(0.0, 1.2, 6.0),
        Vec3::new(0.0, -0.4, 0.0),
        Vec3::Y,
        Projection::Perspective { vfov_deg: 50.0 },
        WIDTH,
        HEIGHT,
    )
    .expect("valid camera");
    BenchScene {
        name: "terrain+spheres",
        meshes,
        transforms,
        camera,
        light: (Vec3::new(1.0, 5.0, 2.0), Vec3::X, Vec3::Z),
    }
}

/// A Cornell-box-like room (millimetres): floor, ceiling, back and side
/// walls, a ceiling light, a front wall of four quads around the opening the
/// camera looks through, and two boxes: ten quads and two boxes.
fn cornell() -> BenchScene {
    let (w, h, d) = (555.0, 548.8, 559.2);
    let p = Vec3::new;
    let (x0, x1, y0, y1) = (150.0, 405.0, 120.0, 430.0);
    let mut meshes = vec![
        quad(
            p(0.0, 0.0, 0.0),
            p(0.0, 0.0, d),
            p(w, 0.0, d),
            p(w, 0.0, 0.0),
        ),
        quad(p(0.0, h, 0.0), p(w, h, 0.0), p(w, h, d), p(0.0, h, d)),
        quad(p(0.0, 0.0, d), p(0.0, h, d), p(w, h, d), p(w, 0.0, d)),
        quad(p(w, 0.0, 0.0), p(w, 0.0, d), p(w, h, d), p(w, h, 0.0)),
        quad(
            p(0.0, 0.0, 0.0),
            p(0.0, h, 0.0),
            p(0.0, h, d),
            p(0.0, 0.0, d),
        ),
        quad(
            p(213.0, h - 0.5, 227.0),
            p(343.0, h - 0.5, 227.0),
            p(343.0, h - 0.5, 332.0),
            p(213.0, h - 0.5, 332.0),
        ),
        quad(
            p(0.0, 0.0, 0.0),
            p(w, 0.0, 0.0),
            p(w, y0, 0.0),
            p(0.0, y0, 0.0),
        ),
        quad(p(0.0, y1, 0.0), p(w, y1, 0.0), p(w, h, 0.0), p(0.0, h, 0.0)),
        quad(
            p(0.0, y0, 0.0),
            p(x0, y0, 0.0),
            p(x0, y1, 0.0),
            p(0.0, y1, 0.0),
        ),
        quad(p(x1, y0, 0.0), p(w, y0, 0.0), p(w, y1, 0.0), p(x1, y1, 0.0)),
    ];
    let mut transforms = vec![Affine3A::IDENTITY; meshes.len()];
    meshes.push(unit_box());
    transforms.push(Affine3A::from_scale_rotation_translation(
        Vec3::splat(165.0),
        Quat::from_rotation_y(-0.29),
        p(185.0, 0.0, 169.0),
    ));
    meshes.push(unit_box());
    transforms.push(Affine3A::from_scale_rotation_translation(
        p(165.0, 330.0, 165.0),
        Quat::from_rotation_y(0.29),
        p(368.0, 0.0, 351.0),
    ));
    let camera = Camera::look_at(
        p(278.0, 273.0, -800.0),
        p(278.0, 273.0, 0.0),
        Vec3::Y,
        Projection::Perspective { vfov_deg: 39.3 },
        WIDTH,
        HEIGHT,
    )
    .expect("valid camera");
    BenchScene {
        name: "cornell",
        meshes,
        transforms,
        camera,
        light: (
            p(213.0, h - 1.0, 227.0),
            p(130.0, 0.0, 0.0),
            p(0.0, 0.0, 105.0),
        ),
    }
}

/// The three ray sets of a scene, traced once with the BVH engine (present
/// in every build) to find the surfaces the secondary rays leave from.
struct RaySets {
    primary: Vec<Ray>,
    diffuse: Vec<Ray>,
    shadow: Vec<Ray>,
}

fn ray_sets(scene: &BenchScene) -> RaySets {
    let cam = &scene.camera;
    let primary: Vec<Ray> = (0..HEIGHT)
        .flat_map(|y| (0..WIDTH).map(move |x| (x, y)))
        .map(|(x, y)| {
            cam.ray(x as f32 + 0.5, y as f32 + 0.5)
                .expect("a pinhole has a ray for every pixel")
        })
        .collect();
    let eng = accel::build(Backend::Bvh, &scene.meshes, &scene.transforms)
        .expect("the BVH engine builds the bench scene");
    let surface: Vec<(Vec3, Vec3, Vec3)> = primary
        .iter()
        .filter_map(|r| eng.intersect(r).map(|h| (r.at(h.t), h.normal, r.dir)))
        .collect();
    assert!(
        !surface.is_empty(),
        "{}: the camera sees nothing",
        scene.name
    );
    let mut rng = Rng(0xBE7C);
    let mut diffuse = Vec::with_capacity(RAYS);
    let mut shadow = Vec::with_capacity(RAYS);
    for i in 0..RAYS {
        let (p, n, incoming) = surface[i % surface.len()];
        let n = if n.dot(incoming) < 0.0 { n } else { -n };
        // Cosine-weighted direction about n.
        let (r, phi) = (rng.f32().sqrt(), TAU * rng.f32());
        let (t, b) = n.any_orthonormal_pair();
        let dir = t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - r * r).max(0.0).sqrt();
        diffuse.push(Ray::new(offset_origin(p, n, dir), dir));
        let (corner, e1, e2) = scene.light;
        let target = corner + e1 * rng.f32() + e2 * rng.f32();
        let origin = offset_origin(p, n, target - p);
        shadow.push(Ray::segment(origin, target - origin, 0.999));
    }
    RaySets {
        primary,
        diffuse,
        shadow,
    }
}

/// Every backend this build has an engine for; a backend that cannot build
/// the scene is reported and left out of the comparison.
fn engines(scene: &BenchScene) -> Vec<(Backend, Box<dyn InstancedEngine>)> {
    Backend::available()
        .iter()
        .filter_map(
            |&b| match accel::build(b, &scene.meshes, &scene.transforms) {
                Ok(e) => Some((b, e)),
                Err(e) => {
                    eprintln!("{}: no {b} engine: {e:#}", scene.name);
                    None
                }
            },
        )
        .collect()
}

fn config() -> Criterion {
    Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3))
}

fn rays(c: &mut Criterion) {
    let scenes = [big_scene(), cornell()];
    let sets: Vec<RaySets> = scenes.iter().map(ray_sets).collect();
    let built: Vec<_> = scenes.iter().map(engines).collect();

    for kind in ["primary", "diffuse"] {
        let mut group = c.benchmark_group(format!("rays/{kind}"));
        for ((scene, set), engines) in scenes.iter().zip(&sets).zip(&built) {
            let rays = if kind == "primary" {
                &set.primary
            } else {
                &set.diffuse
            };
            group.throughput(Throughput::Elements(rays.len() as u64));
            let mut out = vec![None; rays.len()];
            for (backend, eng) in engines {
                group.bench_function(BenchmarkId::new(backend.to_string(), scene.name), |b| {
                    b.iter(|| eng.intersect_batch(rays, &mut out))
                });
            }
        }
        group.finish();
    }

    let mut group = c.benchmark_group("rays/shadow");
    for ((scene, set), engines) in scenes.iter().zip(&sets).zip(&built) {
        group.throughput(Throughput::Elements(set.shadow.len() as u64));
        let mut out = vec![false; set.shadow.len()];
        for (backend, eng) in engines {
            group.bench_function(BenchmarkId::new(backend.to_string(), scene.name), |b| {
                b.iter(|| eng.occluded_batch(&set.shadow, &mut out))
            });
        }
    }
    group.finish();
}

fn build(c: &mut Criterion) {
    let scenes = [big_scene(), cornell()];
    let mut group = c.benchmark_group("build");
    for scene in &scenes {
        let triangles: usize = scene.meshes.iter().map(|m| m.triangles.len()).sum();
        for (backend, mut eng) in engines(scene) {
            group.throughput(Throughput::Elements(triangles as u64));
            group.bench_function(BenchmarkId::new(backend.to_string(), scene.name), |b| {
                b.iter(|| accel::build(backend, &scene.meshes, &scene.transforms).unwrap())
            });
            // Moving every instance: what a new scene time costs.
            let moved: Vec<Affine3A> = scene
                .transforms
                .iter()
                .map(|m| Affine3A::from_translation(Vec3::splat(0.01)) * *m)
                .collect();
            group.throughput(Throughput::Elements(moved.len() as u64));
            let id = BenchmarkId::new(backend.to_string(), format!("{}/update", scene.name));
            group.bench_function(id, |b| b.iter(|| eng.set_transforms(&moved).unwrap()));
        }
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = config();
    targets = rays, build
}
criterion_main!(benches);
