//! An irradiance lookup against the shadow ray the multipass renderer
//! traces at the same point: the lookup replaces a traced diffuse bounce,
//! so it pays only if it costs less than a ray. Both run single-threaded
//! over the same points, the first hits of the Cornell box's 256 x 256
//! pixel-centre camera rays at t = 0.5 (emitters left out), with the
//! records of a q = 0.6 simplification solved at that time; the shadow
//! rays go to fixed random points on the light. Embree where the build has
//! it.

use std::hint::black_box;
use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::Vec3;
use rangewalk::accel::{self, Backend};
use rangewalk::quality::Quality;
use rangewalk::radiosity::lookup::IrradianceCache;
use rangewalk::radiosity::{simplify, solve};
use rangewalk::ray::{offset_origin, Ray};
use rangewalk::rng::SplitMix64;
use rangewalk::scene::Scene;

const SIZE: u32 = 256;
const TIME: f32 = 0.5;

/// A lookup as the multipass renderer makes it: object, side, and the
/// object-space point and normal.
struct Query {
    object: u32,
    front: bool,
    point: Vec3,
    normal: Vec3,
}

fn lookup(c: &mut Criterion) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml");
    let scene = Scene::load(&path).expect("loading the Cornell box");
    let camera = scene
        .camera("main")
        .and_then(|d| d.perspective(SIZE, SIZE))
        .expect("Cornell box camera");
    let backend = Backend::default_available();
    let poses = scene.at(TIME);
    let mut engine = accel::build(backend, &scene.geometry(), &poses).expect("ray engine");
    let quality = Quality::new(0.6).unwrap();
    let simplified = simplify(&scene, engine.as_mut(), quality).expect("simplification");
    engine.set_transforms(&poses).expect("posing the scene");
    let solution = solve(&scene, &simplified, engine.as_ref(), TIME, quality).expect("solve");
    let cache = IrradianceCache::new(&simplified, &solution.indirect).expect("irradiance cache");

    // World-space triangles of the emitters, to aim shadow rays at.
    let mut light = Vec::new();
    for (o, object) in scene.objects.iter().enumerate() {
        if scene.materials[object.material].emission.is_some() {
            for t in &object.mesh.triangles {
                light.push(t.map(|v| poses[o].transform_point3(object.mesh.positions[v as usize])));
            }
        }
    }
    assert!(!light.is_empty(), "the Cornell box has an area light");

    let mut rng = SplitMix64::new(1);
    let (mut queries, mut shadows) = (Vec::new(), Vec::new());
    for y in 0..SIZE {
        for x in 0..SIZE {
            let Some(ray) = camera.ray(x as f32 + 0.5, y as f32 + 0.5) else {
                continue;
            };
            let Some(hit) = engine.intersect(&ray) else {
                continue;
            };
            let object = &scene.objects[hit.object as usize];
            if scene.materials[object.material].emission.is_some() {
                continue;
            }
            let [a, b, c] = object.mesh.triangles[hit.primitive as usize]
                .map(|v| object.mesh.positions[v as usize]);
            let local = a * (1.0 - hit.u - hit.v) + b * hit.u + c * hit.v;
            let p = poses[hit.object as usize].transform_point3(local);
            let front = hit.normal.dot(ray.dir) < 0.0;
            let normal = (b - a).cross(c - a).normalize_or_zero();
            queries.push(Query {
                object: hit.object,
                front,
                point: local,
                normal: if front { normal } else { -normal },
            });
            let [la, lb, lc] = light[(rng.next_f32() * light.len() as f32) as usize % light.len()];
            let (u, v) = (rng.next_f32(), rng.next_f32());
            let (u, v) = if u + v > 1.0 {
                (1.0 - u, 1.0 - v)
            } else {
                (u, v)
            };
            let q = la + (lb - la) * u + (lc - la) * v;
            let wi = (q - p).normalize();
            let origin = offset_origin(p, hit.normal, wi);
            let end = offset_origin(q, (lb - la).cross(lc - la).normalize(), -wi);
            shadows.push(Ray::segment(origin, end - origin, 1.0));
        }
    }

    let mut group = c.benchmark_group("lookup");
    group.throughput(Throughput::Elements(queries.len() as u64));
    group.bench_function(BenchmarkId::new("irradiance", backend), |b| {
        b.iter(|| {
            queries.iter().fold(Vec3::ZERO, |s, q| {
                s + cache.irradiance(q.object, q.front, black_box(q.point), q.normal)
            })
        })
    });
    group.bench_function(BenchmarkId::new("occluded", backend), |b| {
        b.iter(|| {
            shadows
                .iter()
                .filter(|r| engine.occluded(black_box(r)))
                .count()
        })
    });
    group.finish();
}

criterion_group!(benches, lookup);
criterion_main!(benches);
