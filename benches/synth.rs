//! Synthesis speed: 512x512 frames of the Cornell box's walk from sphere
//! base images, against the number of base images and their size. The
//! bases are baked once (1 sample per pixel: synthesis does not care what
//! the pixels hold) into a temporary folder and held in memory, so the
//! figure is frames per second of synthesis alone, as a walk-through sees
//! it after its bases are loaded; each without subpixels and at the
//! default 2 × 2 a pixel.
//!
//! `RANGEWALK_BENCH_BAKES=<dir>` keeps the bakes in `<dir>` and reuses
//! them on the next run (a 2,544² bake takes minutes on two cores), and
//! bases are read only for the benchmarks a filter selects, so that a
//! profile of one of them is of synthesis, not of baking and reading.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rangewalk::accel::{self, Backend};
use rangewalk::bake::{self, BaseProjection, IndirectSource, Settings, Shard};
use rangewalk::plan::{Plan, PlannedView};
use rangewalk::scene::Scene;
use rangewalk::synth::{Options, Synthesizer, TimeInterp, DEFAULT_BUDGET};

const FRAME: u32 = 512;

/// Four views along the view space, each at the animation's two ends.
fn plan(scene: &Scene) -> Plan {
    let Some(rangewalk::scene::ViewSpace::Segment { a, b }) = scene.view_space else {
        panic!("the Cornell box's view space is a segment");
    };
    Plan {
        quality: 0.6,
        views: (0..4)
            .map(|i| PlannedView {
                position: a.lerp(b, i as f32 / 3.0),
                times: vec![0.0, 1.0],
            })
            .collect(),
        light_times: vec![0.0, 1.0],
        ..Plan::default()
    }
}

fn synth(c: &mut Criterion) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml");
    let scene = Scene::load(&path).expect("loading the Cornell box");
    let walk = scene.path("walk").expect("the walk path");
    for size in [1024u32, 2544] {
        let temporary = tempfile::tempdir().expect("temporary folder");
        let dir = match std::env::var_os("RANGEWALK_BENCH_BAKES") {
            Some(d) => PathBuf::from(d).join(size.to_string()),
            None => temporary.path().to_path_buf(),
        };
        let settings = Settings {
            quality: 0.6,
            size,
            spp: 1,
            projection: BaseProjection::Sphere,
            indirect: IndirectSource::Path,
            seed: 1,
            backend: Backend::default_available(),
            max_depth: Some(2),
        };
        let mut engine =
            accel::build(settings.backend, &scene.geometry(), &scene.at(0.0)).expect("ray engine");
        let p = plan(&scene);
        bake::run(
            &scene,
            &dir,
            &settings,
            Shard::ALL,
            engine.as_mut(),
            |_| Ok(p),
        )
        .expect("baking the bases");
        let baked = bake::Bake::open(&dir, &scene).expect("opening the bake");
        let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
        let mut group = c.benchmark_group(format!("synth-512-from-{size}"));
        group.sample_size(20);
        group.throughput(Throughput::Elements(1));
        // (base images, views, time): at a base time one image per view;
        // between times two.
        for (images, views, t, interp) in [
            (1, 1, 0.0, TimeInterp::Motion),
            (2, 2, 0.0, TimeInterp::Motion),
            (4, 4, 0.0, TimeInterp::Motion),
            (4, 2, 0.5, TimeInterp::Linear),
            (4, 2, 0.5, TimeInterp::Motion),
            (8, 4, 0.5, TimeInterp::Motion),
        ] {
            let camera = walk.at(0.5).perspective(FRAME, FRAME).expect("camera");
            // Without subpixels and at the default 2 x 2.
            for supersample in [1, 2] {
                let options = Options {
                    bases: views,
                    time_interp: interp,
                    supersample,
                    ..Options::default()
                };
                let id = format!("{images}-images-{views}-views-{interp:?}-ss{supersample}")
                    .to_lowercase();
                // Criterion calls this only for the benchmarks a filter
                // selects; the bases are loaded before timing.
                let mut loaded = false;
                group.bench_function(BenchmarkId::from_parameter(id), |b| {
                    if !loaded {
                        synth.frame(&camera, t, &options).expect("frame");
                        loaded = true;
                    }
                    b.iter(|| synth.frame(&camera, t, &options).expect("frame"))
                });
            }
        }
        group.finish();
    }
}

criterion_group!(benches, synth);
criterion_main!(benches);
