//! A walk's cost against path tracing its frames at one sample per pixel:
//! the 31 frames of the Cornell box's `walk` path at 512², from opening the
//! bake to the last frame written (what `rangewalk walk` does, at its
//! defaults), and the same 31 frames path traced at 1 spp (the reference
//! path tracer, both cores, each frame at its time). The goal: the walk at
//! most a quarter of the path tracing (`walk / pathtrace-1spp` ≤ 0.25).
//!
//! The bases are those of the bake a user makes for 512² frames at
//! q = 0.6: two views at the ends of the view segment, at t = 0 and 1,
//! 2,544² spheres cut to their windows. Synthesis does not depend on what
//! their pixels hold, so they are baked at one sample with traced indirect
//! light. `RANGEWALK_BENCH_BAKES=<dir>` keeps the bake in `<dir>/walk` and
//! reuses it.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion};
use rangewalk::accel::{self, Backend};
use rangewalk::bake::{self, BaseProjection, IndirectSource, Settings, Shard};
use rangewalk::plan::{Plan, PlannedView};
use rangewalk::quality::Quality;
use rangewalk::render::{self, RenderSettings};
use rangewalk::scene::Scene;
use rangewalk::synth::walk::{self, WalkSettings};
use rangewalk::synth::{Options, Synthesizer, DEFAULT_BUDGET};

const FRAME: u32 = 512;

/// The plan of `rangewalk bake --quality 0.6` for the Cornell box: the view
/// segment's ends at the animation's two ends.
fn plan(scene: &Scene) -> Plan {
    let Some(rangewalk::scene::ViewSpace::Segment { a, b }) = scene.view_space else {
        panic!("the Cornell box's view space is a segment");
    };
    Plan {
        quality: Quality::new(0.6).unwrap(),
        views: [a, b]
            .into_iter()
            .map(|position| PlannedView {
                position,
                times: vec![0.0, 1.0],
            })
            .collect(),
        light_times: vec![0.0, 1.0],
        ..Plan::default()
    }
}

fn walk_against_path_tracing(c: &mut Criterion) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml");
    let scene = Scene::load(&path).expect("loading the Cornell box");
    let temporary = tempfile::tempdir().expect("temporary folder");
    let dir = match std::env::var_os("RANGEWALK_BENCH_BAKES") {
        Some(d) => PathBuf::from(d).join("walk"),
        None => temporary.path().join("bake"),
    };
    let settings = Settings {
        quality: Quality::new(0.6).expect("quality"),
        size: 2544,
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

    let walk_path = scene.path("walk").expect("the walk path").clone();
    let times = walk::frame_times(walk_path.span(), scene.animation.fps);
    assert_eq!(times.len(), 31, "the walk's frames");
    let out = temporary.path().join("frames");
    let mut group = c.benchmark_group("walk-31-frames-512");
    group.sample_size(10);
    group.bench_function("walk", |b| {
        b.iter(|| {
            // Opening the bake is part of the walk's cost.
            let baked = bake::Bake::open(&dir, &scene).expect("opening the bake");
            let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
            let settings = WalkSettings {
                path: "walk".into(),
                width: FRAME,
                height: FRAME,
                fps: None,
                options: Options::default(),
                exposure: 0.0,
            };
            let _ = std::fs::remove_dir_all(&out);
            walk::walk(&mut synth, &settings, &out, None).expect("walking")
        })
    });
    group.bench_function("pathtrace-1spp", |b| {
        let render_settings = RenderSettings {
            spp: 1,
            max_depth: None,
            seed: 1,
        };
        b.iter(|| {
            for &t in &times {
                let camera = walk_path.at(t).perspective(FRAME, FRAME).expect("camera");
                engine.set_transforms(&scene.at(t)).expect("posing");
                render::render(&scene, &*engine, &camera, t, &render_settings)
                    .expect("path tracing");
            }
        })
    });
    group.finish();
}

criterion_group!(benches, walk_against_path_tracing);
criterion_main!(benches);
