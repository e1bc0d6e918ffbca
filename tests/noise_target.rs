//! Sampling base images to a noise target (`render::noise`): pixels
//! without noise stop at the minimum, noisy ones take more, the error
//! reached is the target's within the estimator's own uncertainty, and the
//! result depends on neither the thread count nor the brightness.

use glam::Vec3;
use rangewalk::accel::{self, Backend};
use rangewalk::camera::Camera;
use rangewalk::image::NO_HIT;
use rangewalk::radiosity::lookup::IrradianceCache;
use rangewalk::radiosity::Simplified;
use rangewalk::render::multipass::{self, Indirect, Layers};
use rangewalk::render::noise::{luminance, NoiseTarget};
use rangewalk::render::{Progress, RenderSettings};
use rangewalk::scene::Scene;

mod common;
use common::load;

fn camera(scene: &Scene, size: u32) -> Camera {
    scene
        .camera("main")
        .unwrap()
        .perspective(size, size)
        .unwrap()
}

/// Renders `scene` with indirect light `e` everywhere (a uniform cache):
/// the noise is that of the direct light's samples alone.
fn render(
    scene: &Scene,
    cam: &Camera,
    e: Vec3,
    spp: u32,
    seed: u64,
    target: Option<NoiseTarget>,
) -> Layers {
    let s = Simplified::whole(scene);
    let cache = IrradianceCache::new(&s, &vec![e; s.records.len()]).unwrap();
    let engine = accel::build(Backend::Bvh, &scene.geometry(), &scene.at(0.0)).unwrap();
    let settings = RenderSettings {
        spp,
        max_depth: None,
        seed,
    };
    multipass::render_layers(
        scene,
        engine.as_ref(),
        cam,
        0.0,
        &settings,
        Indirect::Records(&cache),
        target,
        Progress::Pixels(&indicatif::ProgressBar::hidden()),
    )
    .unwrap()
}

fn target(relative: f32, max_spp: u32) -> Option<NoiseTarget> {
    Some(NoiseTarget { relative, max_spp })
}

/// The Cornell box with its light's emission scaled by `k`.
fn cornell_lit(k: f32) -> Scene {
    let mut scene = load("cornell-box");
    for m in &mut scene.materials {
        if let Some(e) = &mut m.emission {
            e.radiance *= k;
        }
    }
    scene
}

#[test]
fn noiseless_pixels_stop_at_the_minimum_and_noisy_ones_take_more() {
    let n = 40;
    // Unlit but for uniform indirect light: inside one object every sample
    // of a pixel is the same, so its window has no variance at all. (A
    // pixel's samples spread over its square: its window's squares are
    // inside one object where the 5 x 5 pixels around it are.)
    let dark = cornell_lit(0.0);
    let cam = camera(&dark, n);
    let out = render(&dark, &cam, Vec3::ONE, 8, 1, target(0.02, 256));
    let ids = &out.image.object_id;
    let w = n as usize;
    let interior = |i: usize| {
        let (x, y) = (i % w, i / w);
        x > 1
            && y > 1
            && x + 2 < w
            && y + 2 < w
            && (y - 2..=y + 2).all(|yy| (x - 2..=x + 2).all(|xx| ids[yy * w + xx] == ids[i]))
    };
    let flat: Vec<usize> = (0..ids.len()).filter(|&i| interior(i)).collect();
    assert!(flat.len() > ids.len() / 4, "{} interior pixels", flat.len());
    for &i in &flat {
        assert_eq!(out.sampling.samples[i], 8, "pixel {i}");
        // The lookup's rounding leaves samples an ulp or so apart.
        assert!(out.sampling.error[i] <= f32::EPSILON, "pixel {i}");
    }

    // Lit: the error of the minimum's mean, measured over 16 independent
    // renders, sorts pixels into quiet (an eighth of the target) and noisy
    // (twice it). A window of quiet pixels stops at the minimum: its
    // estimate, from 63 degrees of freedom, would have to be 64 times its
    // variance (16 times where the first samples' strata, which the estimate
    // ignores, took three quarters of the variance away).
    // Noisy pixels take more.
    let lit = cornell_lit(1.0);
    let runs: Vec<Vec<f64>> = (0..16)
        .map(|seed| {
            let r = render(&lit, &cam, Vec3::ONE, 8, 100 + seed, None);
            r.image.radiance.iter().map(|&c| luminance(c)).collect()
        })
        .collect();
    let k = runs.len() as f64;
    let rel_sd: Vec<f64> = (0..ids.len())
        .map(|i| {
            let mean = runs.iter().map(|r| r[i]).sum::<f64>() / k;
            let var = runs.iter().map(|r| (r[i] - mean).powi(2)).sum::<f64>() / (k - 1.0);
            if mean > 0.0 {
                var.sqrt() / mean
            } else {
                0.0
            }
        })
        .collect();
    let t = 0.02f32;
    let out = render(&lit, &cam, Vec3::ONE, 8, 1, target(t, 256));
    let quiet_window = |i: usize| {
        let (x, y) = (i % w, i / w);
        (y.saturating_sub(1)..(y + 2).min(w)).all(|yy| {
            (x.saturating_sub(1)..(x + 2).min(w)).all(|xx| rel_sd[yy * w + xx] < t as f64 / 8.0)
        })
    };
    let quiet: Vec<usize> = (0..ids.len()).filter(|&i| quiet_window(i)).collect();
    assert!(quiet.len() > 20, "{} quiet pixels", quiet.len());
    for &i in &quiet {
        assert_eq!(out.sampling.samples[i], 8, "pixel {i}, error {}", rel_sd[i]);
    }
    let noisy: Vec<usize> = (0..ids.len())
        .filter(|&i| rel_sd[i] > 2.0 * t as f64)
        .collect();
    assert!(noisy.len() > 20, "{} noisy pixels", noisy.len());
    let mean_spp = noisy
        .iter()
        .map(|&i| out.sampling.samples[i] as f64)
        .sum::<f64>()
        / noisy.len() as f64;
    assert!(mean_spp > 8.0, "noisy pixels: {mean_spp} samples");
}

/// The error reached by the pixels that stopped on the target (not at the
/// limit: a dark pixel that a sliver of the light enters now and then is
/// truly noisier than 4096 samples can mend), against a render of 4096
/// samples per pixel, is at most the target's within what the estimator
/// can tell: a window of nine
/// pixels with at least `spp` samples each estimates a variance from
/// `9 (spp − 1)` degrees of freedom, to a relative standard deviation of
/// `s = √(2 / dof)`; a pixel that stops with its estimate at the target
/// has, three such deviations out, a true variance of `t² / (1 − 3 s)`.
/// The reference's own variance (its estimate) adds to the measured one,
/// and the measured mean of squares has a standard error of its own.
#[test]
fn the_target_is_reached_within_the_estimators_uncertainty() {
    let scene = cornell_lit(1.0);
    let n = 40;
    let cam = camera(&scene, n);
    let e = Vec3::splat(0.3);
    let (spp, t) = (8, 0.05f32);
    let max = 4096;
    let out = render(&scene, &cam, e, spp, 1, target(t, max));
    let reference = render(&scene, &cam, e, 4096, 2, None);
    let y = |img: &[Vec3]| -> Vec<f64> { img.iter().map(|&c| luminance(c)).collect() };
    let (got, want) = (y(&out.image.radiance), y(&reference.image.radiance));
    let w = n as usize;
    let window_mean = |i: usize| {
        let (x, yy) = (i % w, i / w);
        let mut sum = 0.0;
        let mut k = 0.0;
        for b in yy.saturating_sub(1)..(yy + 2).min(w) {
            for a in x.saturating_sub(1)..(x + 2).min(w) {
                sum += want[b * w + a];
                k += 1.0;
            }
        }
        sum / k
    };
    let floor = out.sampling.floor;
    let seen: Vec<usize> = (0..got.len())
        .filter(|&i| out.image.object_id[i] != NO_HIT && out.sampling.samples[i] < max)
        .collect();
    assert!(seen.len() > got.len() / 2, "{} pixels", seen.len());
    let sq: Vec<f64> = seen
        .iter()
        .map(|&i| ((got[i] - want[i]) / window_mean(i).max(floor)).powi(2))
        .collect();
    let m = sq.len() as f64;
    let mean_sq = sq.iter().sum::<f64>() / m;
    let se = (sq.iter().map(|v| (v - mean_sq).powi(2)).sum::<f64>() / (m - 1.0) / m).sqrt();
    let reference_sq = seen
        .iter()
        .map(|&i| (reference.sampling.error[i] as f64).powi(2))
        .sum::<f64>()
        / m;
    let s = (2.0 / (9.0 * (spp as f64 - 1.0))).sqrt();
    let bound = (t as f64).powi(2) / (1.0 - 3.0 * s) + reference_sq + 3.0 * se;
    eprintln!(
        "RMS relative error {} over {} pixels, bound {}",
        mean_sq.sqrt(),
        seen.len(),
        bound.sqrt()
    );
    assert!(
        mean_sq <= bound,
        "RMS relative error {} above the bound {} (target {t})",
        mean_sq.sqrt(),
        bound.sqrt()
    );
    // The estimates themselves say the target is reached.
    assert!(seen.iter().all(|&i| out.sampling.error[i] <= t));
}

#[test]
fn the_same_seed_gives_the_same_pixels_on_any_thread_count() {
    let scene = cornell_lit(1.0);
    let cam = camera(&scene, 24);
    let go = || render(&scene, &cam, Vec3::splat(0.3), 4, 9, target(0.02, 64));
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(go);
    let three = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap()
        .install(go);
    assert!(one.sampling.samples.iter().any(|&n| n > 4));
    assert_eq!(one.sampling, three.sampling);
    let bits = |l: &Layers| -> Vec<u32> {
        l.image
            .radiance
            .iter()
            .chain(&l.indirect)
            .chain(&l.diffuse_direct)
            .flat_map(|c| c.to_array().map(f32::to_bits))
            .collect()
    };
    assert_eq!(bits(&one), bits(&three));
}

/// Relative errors do not depend on the brightness: lights and indirect
/// light scaled by powers of two (exact in floating point) from about
/// 1e-6 to 7e7 take exactly the same samples.
#[test]
fn very_dark_and_very_bright_scenes_take_the_same_samples() {
    let base = cornell_lit(1.0);
    let cam = camera(&base, 24);
    let runs: Vec<Layers> = [-20, 0, 26]
        .map(|p| {
            let k = 2f32.powi(p);
            let scene = cornell_lit(k);
            let out = render(&scene, &cam, Vec3::splat(0.3 * k), 4, 3, target(0.02, 64));
            assert!(out.image.radiance.iter().all(|c| c.is_finite()), "2^{p}");
            out
        })
        .into();
    assert!(runs[1].sampling.samples.iter().any(|&n| n > 4));
    for r in &runs {
        assert_eq!(r.sampling.samples, runs[1].sampling.samples);
        assert_eq!(r.sampling.error, runs[1].sampling.error);
    }
}

/// Walls that reflect 99 % (traced indirect light, long paths) stay
/// finite and within the limit, and the report counts the pixels the
/// limit stopped.
#[test]
fn near_white_walls_stay_finite_and_within_the_limit() {
    let mut scene = load("furnace");
    for m in &mut scene.materials {
        if let rangewalk::scene::Bsdf::Diffuse { reflectance, .. } = &mut m.bsdf {
            *reflectance = Vec3::splat(0.99);
        }
    }
    let cam = camera(&scene, 16);
    let engine = accel::build(Backend::Bvh, &scene.geometry(), &scene.at(0.0)).unwrap();
    let settings = RenderSettings {
        spp: 4,
        max_depth: None,
        seed: 5,
    };
    let (t, max) = (0.01, 32);
    let out = multipass::render_layers(
        &scene,
        engine.as_ref(),
        &cam,
        0.0,
        &settings,
        Indirect::Traced,
        target(t, max),
        Progress::Pixels(&indicatif::ProgressBar::hidden()),
    )
    .unwrap();
    assert!(out.image.radiance.iter().all(|c| c.is_finite()));
    let s = &out.sampling;
    assert!(s.samples.iter().all(|&n| (4..=max).contains(&n)));
    let limited = (0..s.samples.len())
        .filter(|&i| s.samples[i] == max && s.error[i] > t)
        .count();
    assert!(limited > 0, "a 1 % target at 32 samples stops some pixels");
    assert_eq!(
        s.report.at_limit,
        Some(limited as f64 / s.samples.len() as f64)
    );
}
