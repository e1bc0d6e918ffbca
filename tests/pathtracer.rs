//! Analytic oracles for the path tracer: furnaces with known radiance,
//! energy conservation of the glossy lobes, determinism across thread
//! counts, scale invariance and robustness to extreme inputs.

use std::path::PathBuf;

use glam::Vec3;
use rangewalk::accel::{self, Backend};
use rangewalk::camera::{Camera, Projection};
use rangewalk::image::RangeImage;
use rangewalk::render::{render, RenderSettings, RenderStats};
use rangewalk::scene::{Bsdf, Emission, GlossyModel, Scene};

fn load(name: &str) -> Scene {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
        .join("scene.toml");
    Scene::load(&path).unwrap_or_else(|e| panic!("{e:#}"))
}

fn render_with(
    backend: Backend,
    scene: &Scene,
    camera: &Camera,
    time: f32,
    settings: RenderSettings,
) -> (RangeImage, RenderStats) {
    let engine = accel::build(backend, &scene.geometry(), &scene.at(time)).unwrap();
    render(scene, engine.as_ref(), camera, time, &settings).unwrap()
}

fn run(scene: &Scene, camera: &Camera, time: f32, settings: RenderSettings) -> RangeImage {
    render_with(Backend::Bvh, scene, camera, time, settings).0
}

fn settings(spp: u32, seed: u64) -> RenderSettings {
    RenderSettings {
        spp,
        max_depth: None,
        seed,
    }
}

fn mean(img: &RangeImage) -> Vec3 {
    img.radiance.iter().sum::<Vec3>() / img.len() as f32
}

/// The furnace cube with every surface reflecting `bsdf` and emitting 1 on
/// both sides, seen from inside.
fn furnace(bsdf: Bsdf) -> (Scene, Camera) {
    let mut scene = load("furnace");
    scene.materials[0].bsdf = bsdf;
    scene.materials[0].emission = Some(Emission {
        radiance: Vec3::ONE,
        two_sided: true,
    });
    let camera = scene.camera("main").unwrap().perspective(16, 16).unwrap();
    (scene, camera)
}

fn diffuse(rho: f32) -> Bsdf {
    Bsdf::Diffuse {
        reflectance: Vec3::splat(rho),
        texture: None,
    }
}

#[test]
fn furnace_radiance_is_emission_over_one_minus_reflectance() {
    for (rho, spp, tol) in [(0.5, 64, 0.01), (0.99, 64, 0.05)] {
        let (scene, camera) = furnace(diffuse(rho));
        let (img, stats) = render_with(Backend::Bvh, &scene, &camera, 0.0, settings(spp, 1));
        let expect = 1.0 / (1.0 - rho);
        let m = mean(&img);
        assert!(
            ((m - Vec3::splat(expect)) / expect).abs().max_element() < tol,
            "rho {rho}: mean radiance {m}, expected {expect}"
        );
        // Paths are long (100 bounces on average at rho = 0.99) but end.
        let per_sample = stats.rays as f64 / stats.samples as f64;
        eprintln!(
            "rho {rho}: mean {m}, {per_sample:.1} rays per sample, {:.2} s",
            stats.seconds
        );
        assert!(per_sample < 4.0 / (1.0 - rho as f64) + 4.0);
        for c in &img.radiance {
            assert!(c.is_finite() && c.min_element() > 0.0);
        }
    }
}
