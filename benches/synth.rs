//! Synthesis speed: 512x512 frames of the Cornell box's walk from sphere
//! base images, against the number of base images and their size. The
//! bases are baked once (1 sample per pixel: synthesis does not care what
//! the pixels hold) into a temporary folder and held in memory, so the
//! figure is frames per second of synthesis alone, as a walk-through sees
//! it after its bases are loaded; each without subpixels and at the
//! default 2 × 2 a pixel, and each again with `Filter::Cover` (ids ending
//! in `-cover`) and with `Blend::Nearest` (`-nearest`), where bases after
//! the nearest are projected only where it leaves something to add.
//!
//! `RANGEWALK_BENCH_BAKES=<dir>` keeps the bakes in `<dir>` and reuses
//! them on the next run (a 2,544² bake takes minutes on two cores), and
//! bases are read only for the benchmarks a filter selects, so that a
//! profile of one of them is of synthesis, not of baking and reading.
//! `RANGEWALK_BENCH_CHECK=1` prints a digest of every selected benchmark's
//! frame (and of the same frame re-shaded) before timing it, so that two
//! builds can be shown to make the same frames. `RANGEWALK_BENCH_CPU=<n>`
//! prints the processor time (both cores' together) and wall time of `n`
//! frames per benchmark: on a machine others load, processor time
//! compares two builds better than wall time.

use std::hash::{DefaultHasher, Hash, Hasher};
use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rangewalk::accel::{self, Backend};
use rangewalk::bake::{self, BaseProjection, IndirectSource, Settings, Shard};
use rangewalk::image::RangeImage;
use rangewalk::plan::{Plan, PlannedView};
use rangewalk::scene::Scene;
use rangewalk::synth::{Blend, Filter, Options, Synthesizer, TimeInterp, DEFAULT_BUDGET};

const FRAME: u32 = 512;

/// Four views along the view space, each at the animation's two ends.
fn plan(scene: &Scene) -> Plan {
    let Some(rangewalk::scene::ViewSpace::Segment { a, b }) = scene.view_space else {
        panic!("the Cornell box's view space is a segment");
    };
    Plan {
        quality: rangewalk::quality::Quality::new(0.6).unwrap(),
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
            quality: rangewalk::quality::Quality::new(0.6).expect("0.6 is a quality"),
            size,
            spp: 1,
            projection: BaseProjection::Sphere,
            indirect: IndirectSource::Path,
            seed: 1,
            backend: Backend::default_available(),
            max_depth: Some(2),
            planning: Default::default(),
        };
        let mut engine =
            accel::build(settings.backend, &scene.geometry(), &scene.at(0.0)).expect("ray engine");
        let p = plan(&scene);
        bake::run(&scene, &dir, &settings, Shard::ALL, engine.as_mut(), |_| {
            Ok(p)
        })
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
            // Without subpixels and at the default 2 x 2; splats as box
            // filters (the default) and reaching only covered pixels; bases
            // averaged (the default) and nearest first.
            for (supersample, filter, blend) in [1, 2].into_iter().flat_map(|s| {
                [Filter::Box, Filter::Cover]
                    .into_iter()
                    .flat_map(move |f| [(s, f, Blend::Average), (s, f, Blend::Nearest)])
            }) {
                let options = Options {
                    bases: views,
                    time_interp: interp,
                    supersample,
                    filter,
                    blend,
                    ..Options::default()
                };
                let suffix = match (filter, blend) {
                    (Filter::Box, Blend::Average) => "",
                    (Filter::Cover, Blend::Average) => "-cover",
                    (Filter::Box, Blend::Nearest) => "-nearest",
                    (Filter::Cover, Blend::Nearest) => "-cover-nearest",
                };
                let id =
                    format!("{images}-images-{views}-views-{interp:?}-ss{supersample}{suffix}")
                        .to_lowercase();
                // Criterion calls this only for the benchmarks a filter
                // selects; the bases are loaded before timing.
                let mut loaded = false;
                group.bench_function(BenchmarkId::from_parameter(id), |b| {
                    if !loaded {
                        let (frame, _) = synth.frame(&camera, t, &options).expect("frame");
                        if std::env::var_os("RANGEWALK_BENCH_CHECK").is_some() {
                            let reshade = Options {
                                time_interp: TimeInterp::Reshade,
                                ..options
                            };
                            let (reshaded, _) = synth.frame(&camera, t, &reshade).expect("frame");
                            println!("digest {} {}", digest(&frame), digest(&reshaded));
                        }
                        if let Some(n) = std::env::var("RANGEWALK_BENCH_CPU")
                            .ok()
                            .and_then(|n| n.parse::<u32>().ok())
                        {
                            let (cpu, wall) = (cpu_seconds(), std::time::Instant::now());
                            for _ in 0..n {
                                synth.frame(&camera, t, &options).expect("frame");
                            }
                            let per = |s: f64| 1e3 * s / n as f64;
                            println!(
                                "cpu {:.2} ms wall {:.2} ms a frame",
                                per(cpu_seconds() - cpu),
                                per(wall.elapsed().as_secs_f64())
                            );
                        }
                        loaded = true;
                    }
                    b.iter(|| synth.frame(&camera, t, &options).expect("frame"))
                });
            }
        }
        group.finish();
    }
}

/// Processor time the process has used, user and system (Linux).
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    // Fields after the command's closing parenthesis; utime and stime are
    // the 14th and 15th of the line, in clock ticks of 1/100 s.
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<f64> = rest
        .split_whitespace()
        .skip(11)
        .take(2)
        .filter_map(|v| v.parse().ok())
        .collect();
    f.iter().sum::<f64>() / 100.0
}

/// A hash of every bit of a frame.
fn digest(image: &RangeImage) -> String {
    let mut h = DefaultHasher::new();
    for (((c, d), (o, p)), n) in image
        .radiance
        .iter()
        .zip(&image.distance)
        .zip(image.object_id.iter().zip(&image.primitive_id))
        .zip(&image.normal)
    {
        (c.to_array().map(f32::to_bits), d.to_bits(), o, p).hash(&mut h);
        n.to_array().map(f32::to_bits).hash(&mut h);
    }
    format!("{:016x}", h.finish())
}

criterion_group!(benches, synth);
criterion_main!(benches);
