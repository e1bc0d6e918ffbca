//! Hierarchical radiosity solve times on the scenes as the pipeline gives
//! them to the solver (simplified at each quality): the Cornell box at three
//! qualities on every backend in the build, the studio at q = 0.9, and the
//! box cut into about 8,000 and 33,000 patches.

use std::path::PathBuf;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::Vec3;
use rangewalk::accel::{self, Backend};
use rangewalk::quality::Quality;
use rangewalk::radiosity::formfactor::subdivide;
use rangewalk::radiosity::{simplify, solve, Simplified};
use rangewalk::scene::Scene;

fn bundled(name: &str) -> Scene {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{name}/scene.toml"));
    Scene::load(&path).unwrap_or_else(|e| panic!("{e:#}"))
}

fn cornell() -> Scene {
    bundled("cornell-box")
}

fn cornell_box(c: &mut Criterion) {
    let scene = cornell();
    let mut group = c.benchmark_group("radiosity_cornell");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(10));
    for &backend in Backend::available() {
        let mut engine = accel::build(backend, &scene.geometry(), &scene.at(0.0)).unwrap();
        for q in [0.3f32, 0.6, 0.9] {
            let quality = Quality::new(q).unwrap();
            let simplified = simplify(&scene, engine.as_mut(), quality).unwrap();
            engine.set_transforms(&scene.at(0.0)).unwrap();
            group.bench_with_input(
                BenchmarkId::new(backend.to_string(), q),
                &quality,
                |b, &quality| {
                    b.iter(|| solve(&scene, &simplified, engine.as_ref(), 0.0, quality).unwrap())
                },
            );
        }
    }
    group.finish();
}

/// Every Cornell box triangle cut 4-way `levels` times, as patches.
fn cut(scene: &Scene, levels: u32) -> Simplified {
    let mut triangles: Vec<(u32, [Vec3; 3])> = Vec::new();
    for (i, o) in scene.objects.iter().enumerate() {
        for t in &o.mesh.triangles {
            triangles.push((i as u32, t.map(|k| o.mesh.positions[k as usize])));
        }
    }
    for _ in 0..levels {
        triangles = triangles
            .into_iter()
            .flat_map(|(o, t)| subdivide(t).map(|c| (o, c)))
            .collect();
    }
    Simplified::from_triangles(scene, triangles)
}

fn many_patches(c: &mut Criterion) {
    let scene = cornell();
    // 32 triangles x 4^4 = 8,192 and x 4^5 = 32,768: bracket 20,000.
    let mut group = c.benchmark_group("radiosity_patches");
    group.sample_size(10);
    let backend = Backend::default_available();
    let engine = accel::build(backend, &scene.geometry(), &scene.at(0.0)).unwrap();
    for levels in [4u32, 5] {
        let simplified = cut(&scene, levels);
        let quality = Quality::new(0.5).unwrap();
        group.bench_with_input(
            BenchmarkId::new(backend.to_string(), simplified.patches.len()),
            &simplified,
            |b, s| b.iter(|| solve(&scene, s, engine.as_ref(), 0.0, quality).unwrap()),
        );
    }
    group.finish();
}

/// The studio (72,310 triangles, sunlit) at q = 0.9, simplified to about
/// 14,500 patches.
fn studio(c: &mut Criterion) {
    let scene = bundled("studio");
    let mut group = c.benchmark_group("radiosity_studio");
    group.sample_size(10);
    let backend = Backend::default_available();
    let mut engine = accel::build(backend, &scene.geometry(), &scene.at(0.0)).unwrap();
    let quality = Quality::new(0.9).unwrap();
    let simplified = simplify(&scene, engine.as_mut(), quality).unwrap();
    engine.set_transforms(&scene.at(0.0)).unwrap();
    group.bench_function(BenchmarkId::new(backend.to_string(), 0.9), |b| {
        b.iter(|| solve(&scene, &simplified, engine.as_ref(), 0.0, quality).unwrap())
    });
    group.finish();
}

criterion_group!(benches, cornell_box, studio, many_patches);
criterion_main!(benches);
