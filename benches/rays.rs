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
use rangewalk::accel::{self, Backend, InstancedEngine};
use rangewalk::camera::{Camera, Projection};
use rangewalk::ray::{offset_origin, Ray};
use rangewalk::rng::SplitMix64;
use rangewalk::scene::MeshGeometry;
use rangewalk::scene::Scene;

/// Pixels of the primary-ray image, and rays of the other kinds.
const WIDTH: u32 = 256;
const HEIGHT: u32 = 256;
const RAYS: usize = (WIDTH * HEIGHT) as usize;

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

/// The bundled Cornell box at t = 0, seen by its camera `main`; shadow rays
/// go to its ceiling light.
fn cornell() -> BenchScene {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-box/scene.toml");
    let scene = Scene::load(path).expect("the bundled Cornell box loads");
    let camera = scene
        .camera("main")
        .and_then(|c| c.perspective(WIDTH, HEIGHT))
        .expect("the Cornell box has a camera `main`");
    let light = scene
        .objects
        .iter()
        .find(|o| o.name == "light")
        .expect("the Cornell box has a light");
    let v = &light.mesh.positions;
    BenchScene {
        name: "cornell",
        meshes: scene.geometry(),
        transforms: scene.at(0.0),
        camera,
        light: (v[0], v[1] - v[0], v[3] - v[0]),
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
    let mut rng = SplitMix64::new(0xBE7C);
    let mut diffuse = Vec::with_capacity(RAYS);
    let mut shadow = Vec::with_capacity(RAYS);
    for i in 0..RAYS {
        let (p, n, incoming) = surface[i % surface.len()];
        let n = if n.dot(incoming) < 0.0 { n } else { -n };
        // Cosine-weighted direction about n.
        let (r, phi) = (rng.next_f32().sqrt(), TAU * rng.next_f32());
        let (t, b) = n.any_orthonormal_pair();
        let dir = t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - r * r).max(0.0).sqrt();
        diffuse.push(Ray::new(offset_origin(p, n, dir), dir));
        let (corner, e1, e2) = scene.light;
        let target = corner + e1 * rng.next_f32() + e2 * rng.next_f32();
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
            #[cfg(feature = "embree")]
            {
                // The wrapper's overhead: the same rays one call at a time
                // through `RayEngine`, and a bare `rtcIntersect1` loop.
                let eng = bare_embree(scene);
                group.bench_function(BenchmarkId::new("embree-single", scene.name), |b| {
                    b.iter(|| {
                        rays.iter()
                            .filter(|r| accel::RayEngine::intersect(&eng, r).is_some())
                            .count()
                    })
                });
                group.bench_function(BenchmarkId::new("embree-bare", scene.name), |b| {
                    b.iter(|| eng.bare_intersect(rays))
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
        #[cfg(feature = "embree")]
        {
            let eng = bare_embree(scene);
            group.bench_function(BenchmarkId::new("embree-single", scene.name), |b| {
                b.iter(|| {
                    set.shadow
                        .iter()
                        .filter(|r| accel::RayEngine::occluded(&eng, r))
                        .count()
                })
            });
            group.bench_function(BenchmarkId::new("embree-bare", scene.name), |b| {
                b.iter(|| eng.bare_occluded(&set.shadow))
            });
        }
    }
    group.finish();
}

#[cfg(feature = "embree")]
fn bare_embree(scene: &BenchScene) -> rangewalk::accel::embree::EmbreeEngine {
    rangewalk::accel::embree::EmbreeEngine::new(&scene.meshes, &scene.transforms)
        .expect("Embree builds the bench scene")
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
