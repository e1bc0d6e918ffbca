//! Base-image bake throughput: one full-sphere base image of the Cornell box
//! by the multipass renderer, indirect light looked up from radiosity
//! records (the default) or traced, for every ray engine in this build. The
//! throughput is in shaded rays (camera, shadow and bounce rays, first-hit
//! rays included), the figure bakes are judged by.
//!
//! And opening a base as synthesis does: one Cornell box base image of
//! the size a 512² walk reads (a 1040 × 688 window of a 2544² sphere),
//! decoded from its EXR and hashed whole, against read from its planes
//! file, every chunk checked.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rangewalk::accel::{self, Backend};
use rangewalk::camera::{Camera, Projection};
use rangewalk::image;
use rangewalk::quality::Quality;
use rangewalk::radiosity::lookup::IrradianceCache;
use rangewalk::radiosity::{self, temporal};
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

fn open(c: &mut Criterion) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml");
    let scene = Scene::load(&path).expect("loading the Cornell box");
    let engine = accel::build(
        Backend::default_available(),
        &scene.geometry(),
        &scene.at(0.0),
    )
    .expect("ray engine");
    // The window the 512² bake holds of its first view's sphere.
    let camera = Camera::looking(
        glam::Vec3::new(78.0, 273.0, -800.0),
        glam::Vec3::Z,
        glam::Vec3::Y,
        Projection::Sphere,
        2544,
        2544,
    )
    .and_then(|c| c.cropped(896, 896, 1040, 688))
    .expect("sphere camera");
    let settings = RenderSettings {
        spp: 1,
        max_depth: None,
        seed: 1,
    };
    let out = multipass::render_layers(
        &scene,
        engine.as_ref(),
        &camera,
        0.0,
        &settings,
        Indirect::Traced,
        None,
        Progress::Pixels(&indicatif::ProgressBar::hidden()),
    )
    .expect("base image");
    let direct: Vec<glam::Vec3> = (out.image.radiance.iter().zip(&out.indirect))
        .map(|(l, i)| *l - *i)
        .collect();
    let dir = tempfile::tempdir().expect("temporary folder");
    let exr = dir.path().join("base.exr");
    let sum = image::write_exr_with_layers(
        &exr,
        &out.image,
        &[
            ("direct", &direct),
            ("indirect", &out.indirect),
            ("diffuse_direct", &out.diffuse_direct),
        ],
    )
    .expect("writing the EXR");
    let planes = dir.path().join("base.exr.planes");
    let sum = rangewalk::checksum::hex(sum);
    // As a bake writes it (version 3), and as bakes of manifest version 7
    // did (version 2, the range image whole).
    let base = image::planes_file::BasePlanes::of(out.image.clone());
    image::planes_file::write_base(&planes, &base, &sum).expect("writing the planes file");
    let planes_v2 = dir.path().join("base-v2.exr.planes");
    image::planes_file::write(&planes_v2, &out.image, &sum).expect("writing the planes file");

    let mut group = c.benchmark_group("open-base");
    group.sample_size(10);
    group.throughput(Throughput::Elements(out.image.len() as u64));
    group.bench_function(BenchmarkId::new("exr", "1040x688"), |b| {
        b.iter(|| image::read_exr_with_layers_hashed(&exr, &[]).expect("reading the EXR"))
    });
    group.bench_function(BenchmarkId::new("planes", "1040x688"), |b| {
        b.iter(|| image::planes_file::read_base(&planes, &sum).expect("reading the planes"))
    });
    group.bench_function(BenchmarkId::new("planes-v2", "1040x688"), |b| {
        b.iter(|| image::planes_file::read(&planes_v2, &sum).expect("reading the planes"))
    });
    group.finish();
}

criterion_group!(benches, bake, open);
criterion_main!(benches);
