//! Path-tracer throughput (pixel samples per second) on the Cornell box at a
//! small size, for every ray engine in this build.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rangewalk::accel::{self, Backend};
use rangewalk::render::{render, RenderSettings};
use rangewalk::scene::Scene;

const SIZE: u32 = 64;
const SPP: u32 = 4;

fn pathtrace(c: &mut Criterion) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml");
    let scene = Scene::load(&path).expect("loading the Cornell box");
    let camera = scene
        .camera("main")
        .and_then(|d| d.perspective(SIZE, SIZE))
        .expect("Cornell box camera");
    let settings = RenderSettings {
        spp: SPP,
        max_depth: None,
        seed: 1,
    };
    let mut group = c.benchmark_group("pathtrace-cornell");
    group.sample_size(10);
    group.throughput(Throughput::Elements((SIZE * SIZE * SPP) as u64));
    for &backend in Backend::available() {
        let engine = match accel::build(backend, &scene.geometry(), &scene.at(0.0)) {
            Ok(e) => e,
            Err(e) => {
                eprintln!("skipping {backend}: {e:#}");
                continue;
            }
        };
        group.bench_function(BenchmarkId::new(backend.to_string(), SIZE), |b| {
            b.iter(|| render(&scene, engine.as_ref(), &camera, 0.0, &settings).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, pathtrace);
criterion_main!(benches);
