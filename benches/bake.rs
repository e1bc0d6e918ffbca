//! Base-image bake throughput: one full-sphere base image of the Cornell box
//! by the multipass renderer, indirect light looked up from radiosity
//! records (the default) or traced, for every ray engine in this build. The
//! throughput is in shaded rays (camera, shadow and bounce rays, first-hit
//! rays included), the figure bakes are judged by.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rangewalk::accel::{self, Backend};
use rangewalk::camera::{Camera, Projection};
use rangewalk::radiosity::lookup::IrradianceCache;
use rangewalk::radiosity::{self, temporal, Quality};
use rangewalk::render::multipass::{self, Indirect};
use rangewalk::render::{Progress, RenderSettings};
use rangewalk::scene::Scene;

const SIZE: u32 = 192;
const SPP: u32 = 8;
const TIME: f32 = 0.5;

fn bake(c: &mut Criterion) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml");
    let scene = Scene::load(&path).expect("loading the Cornell box");
    let q = Quality::new(0.6).expect("quality");
    let mut solver = accel::build(
        Backend::default_available(),
        &scene.geometry(),
        &scene.at(0.0),
    )
    .expect("ray engine");
    let simplified = radiosity::simplify(&scene, solver.as_mut(), q).expect("simplification");
    let series = temporal::decompose(&scene, &simplified, solver.as_mut(), q).expect("radiosity");
    let cache =
        IrradianceCache::new(&simplified, &series.indirect_at(TIME)).expect("irradiance cache");
    // The first base view of the Cornell box: the view space's left end.
    let camera = Camera::looking(
        glam::Vec3::new(78.0, 273.0, -800.0),
        glam::Vec3::Z,
        glam::Vec3::Y,
        Projection::Sphere,
        SIZE,
        SIZE,
    )
    .expect("sphere camera");
    let settings = RenderSettings {
        spp: SPP,
        max_depth: None,
        seed: 1,
    };
    for (name, indirect) in [
        ("records", Indirect::Records(&cache)),
        ("traced", Indirect::Traced),
    ] {
        let mut group = c.benchmark_group(format!("bake-cornell-{name}"));
        group.sample_size(10);
        for &backend in Backend::available() {
            let engine = accel::build(backend, &scene.geometry(), &scene.at(TIME))
                .unwrap_or_else(|e| panic!("{backend}: {e:#}"));
            let render = || {
                multipass::render_layers(
                    &scene,
                    engine.as_ref(),
                    &camera,
                    TIME,
                    &settings,
                    indirect,
                    None,
                    Progress::Pixels(&indicatif::ProgressBar::hidden()),
                )
                .expect("base image")
            };
            // The same seed traces the same rays every time.
            group.throughput(Throughput::Elements(render().stats.rays));
            group.bench_function(BenchmarkId::new(backend.to_string(), SIZE), |b| {
                b.iter(render)
            });
        }
        group.finish();
    }
}

criterion_group!(benches, bake);
criterion_main!(benches);
