//! Converged path-traced references, cached as range images so that a
//! rerun of an experiment (another quality, another renderer setting) does
//! not pay for them again.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use glam::Vec3;

use crate::accel::InstancedEngine;
use crate::camera::Camera;
use crate::eval::metrics;
use crate::image;
use crate::render::{self, RenderSettings};
use crate::scene::hash::ContentHash;
use crate::scene::Scene;

/// Seed of every reference; test renders use other seeds so that their
/// noise is independent of the reference's (the same seed would replay the
/// reference's first samples and understate the error).
pub const REFERENCE_SEED: u64 = 0;

/// Seed of the second half of every reference's samples: the two halves
/// are independent renders, whose difference measures the reference's
/// own noise ([`Reference::noise`]).
pub const REFERENCE_SEED_2: u64 = 0x2ef_5eed_0002;

/// One reference frame.
#[derive(Clone, Debug)]
pub struct Reference {
    pub radiance: Vec<Vec3>,
    /// Path-tracing time; unknown for a cache entry from before times were
    /// recorded beside it.
    pub seconds: Option<f64>,
    /// Whether it came from the cache.
    pub reused: bool,
    /// LRMS of the reference's own noise, from the difference of two
    /// independent halves of its samples: a synthesized frame with true
    /// error `e` measures about `√(e² + noise²)` against it. `None` for
    /// one sample per pixel (nothing to halve) and for cache entries from
    /// before it was kept.
    pub noise: Option<f64>,
}

/// References of `camera`'s view at each of `times` with `spp` samples per
/// pixel, read from `dir` where an earlier run left them, else rendered
/// (moving `engine` to each time) and stored there.
///
/// Entries are keyed by the scene (its file and geometry), camera, image
/// size, sample count and time; textures read from other files are not part
/// of the key.
pub fn references(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    camera: &Camera,
    camera_name: &str,
    times: &[f32],
    spp: u32,
    dir: &Path,
) -> Result<Vec<Reference>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let id = scene_id(scene)?;
    let mut out = Vec::with_capacity(times.len());
    for (i, &t) in times.iter().enumerate() {
        let path = dir.join(format!(
            "{id}-{camera_name}-{}x{}-spp{spp}-t{t:.6}.exr",
            camera.width, camera.height
        ));
        let seconds_path = path.with_extension("seconds");
        let noise_path = path.with_extension("noise");
        let number = |p: &Path| {
            std::fs::read_to_string(p)
                .ok()
                .and_then(|s| s.trim().parse::<f64>().ok())
        };
        if let Some(radiance) = cached(&path, camera, t) {
            let (seconds, noise) = (number(&seconds_path), number(&noise_path));
            eprintln!(
                "reference {}/{}: t = {t} s, reused {}",
                i + 1,
                times.len(),
                path.display()
            );
            out.push(Reference {
                radiance,
                seconds,
                reused: true,
                noise,
            });
            continue;
        }
        eprintln!(
            "reference {}/{}: t = {t} s, path tracing {}x{} at {spp} spp",
            i + 1,
            times.len(),
            camera.width,
            camera.height
        );
        let (img, seconds, noise) = halves(scene, engine, camera, t, spp)?;
        // The image last: an entry counts as cached only once its EXR is
        // there, so the numbers beside it are never stale.
        if let Some(noise) = noise {
            std::fs::write(&noise_path, format!("{noise}\n"))
                .with_context(|| format!("writing {}", noise_path.display()))?;
        }
        std::fs::write(&seconds_path, format!("{seconds}\n"))
            .with_context(|| format!("writing {}", seconds_path.display()))?;
        image::write_exr(&path, &img)?;
        out.push(Reference {
            radiance: img.radiance,
            seconds: Some(seconds),
            reused: false,
            noise,
        });
    }
    Ok(out)
}

/// A reference of `spp` samples as the mean of two independent renders of
/// half of them each, with the time both took and the mean's noise
/// ([`metrics::noise_of_mean`]); one render where there is one sample.
fn halves(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    camera: &Camera,
    t: f32,
    spp: u32,
) -> Result<(image::RangeImage, f64, Option<f64>)> {
    let first = spp.div_ceil(2);
    let (mut img, seconds) = path_trace_image(scene, engine, camera, t, first, REFERENCE_SEED)?;
    let second = spp - first;
    if second == 0 {
        return Ok((img, seconds, None));
    }
    let (other, more) = path_trace_image(scene, engine, camera, t, second, REFERENCE_SEED_2)?;
    let noise = metrics::noise_of_mean(&img.radiance, first, &other.radiance, second)?;
    let (wa, wb) = (first as f32 / spp as f32, second as f32 / spp as f32);
    for (a, b) in img.radiance.iter_mut().zip(&other.radiance) {
        *a = *a * wa + *b * wb;
    }
    Ok((img, seconds + more, Some(noise)))
}

/// The report's note on the references' own noise: what no method can get
/// under against them.
pub fn noise_note(references: &[Reference]) -> Option<String> {
    let mut noise: Vec<f64> = references.iter().filter_map(|r| r.noise).collect();
    if noise.is_empty() {
        return None;
    }
    noise.sort_by(f64::total_cmp);
    let median = noise[noise.len() / 2];
    let unknown = references.len() - noise.len();
    Some(format!(
        "the references' own noise (two independent halves of their samples): LRMS {median:.3} \
         (median of {}{}; {:.3}–{:.3}); a frame of true error e measures about √(e² + {median:.3}²) \
         against them",
        noise.len(),
        if unknown > 0 {
            format!(", {unknown} cached without it")
        } else {
            String::new()
        },
        noise[0],
        noise[noise.len() - 1],
    ))
}

/// The report's note on references read from the cache, if any were.
pub fn reuse_note(references: &[Reference]) -> Option<String> {
    let reused = references.iter().filter(|r| r.reused).count();
    (reused > 0).then(|| {
        format!(
            "{reused} of {} references reused from an earlier run",
            references.len()
        )
    })
}

/// Path-traced radiance of `camera`'s view at `t` and the rendering time.
pub fn path_trace(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    camera: &Camera,
    t: f32,
    spp: u32,
    seed: u64,
) -> Result<(Vec<Vec3>, f64)> {
    let (img, seconds) = path_trace_image(scene, engine, camera, t, spp, seed)?;
    Ok((img.radiance, seconds))
}

/// [`path_trace`], the whole range image.
pub(crate) fn path_trace_image(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    camera: &Camera,
    t: f32,
    spp: u32,
    seed: u64,
) -> Result<(image::RangeImage, f64)> {
    engine.set_transforms(&scene.at(t))?;
    let settings = RenderSettings {
        spp,
        max_depth: None,
        seed,
    };
    let (img, stats) = render::render(scene, &*engine, camera, t, &settings)?;
    Ok((img, stats.seconds))
}

/// The cached radiance at `path` if it is a readable range image of this
/// camera's size and time (anything else is rendered anew).
fn cached(path: &Path, camera: &Camera, t: f32) -> Option<Vec<Vec3>> {
    if !path.exists() {
        return None;
    }
    match image::read_exr(path) {
        Ok(img)
            if img.width == camera.width
                && img.height == camera.height
                && img.meta.time == t
                && img.radiance.iter().all(|c| c.is_finite()) =>
        {
            Some(img.radiance)
        }
        Ok(_) => {
            eprintln!(
                "note: {} does not match; rendering it again",
                path.display()
            );
            None
        }
        Err(e) => {
            eprintln!("note: {e:#}; rendering it again");
            None
        }
    }
}

/// A file-name-safe identity of the scene: its folder's name and a hash of
/// the scene file and the loaded geometry (so that editing either one
/// invalidates the cache).
fn scene_id(scene: &Scene) -> Result<String> {
    let hash = ContentHash::of(scene)?;
    let name: String = folder_name(&scene.source)
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    Ok(format!("{name}-{}", hash.total))
}

fn folder_name(source: &Path) -> String {
    let stem = source.file_stem().map(PathBuf::from).unwrap_or_default();
    match source.parent().and_then(|p| p.file_name()) {
        Some(dir) if stem.as_os_str() == "scene" => dir.to_string_lossy().into_owned(),
        _ => stem.to_string_lossy().into_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{self, Backend};

    #[test]
    fn references_are_rendered_once_and_then_reused() {
        let scene = Scene::load(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/cornell-box/scene.toml"
        ))
        .unwrap();
        let camera = scene.camera("main").unwrap().perspective(8, 8).unwrap();
        let mut engine = accel::build(Backend::Bvh, &scene.geometry(), &scene.at(0.0)).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let times = [0.0, 1.0];
        let first = references(
            &scene,
            engine.as_mut(),
            &camera,
            "main",
            &times,
            2,
            dir.path(),
        )
        .unwrap();
        assert!(first
            .iter()
            .all(|r| !r.reused && r.seconds.is_some() && r.noise.is_some()));
        // The two ends of the animation differ (the boxes moved).
        assert_ne!(first[0].radiance, first[1].radiance);
        let again = references(
            &scene,
            engine.as_mut(),
            &camera,
            "main",
            &times,
            2,
            dir.path(),
        )
        .unwrap();
        for (a, b) in first.iter().zip(&again) {
            assert!(b.reused);
            assert_eq!(a.radiance, b.radiance);
            assert_eq!(a.seconds, b.seconds);
            assert_eq!(a.noise, b.noise);
        }
        // Another sample count is another entry.
        let other = references(
            &scene,
            engine.as_mut(),
            &camera,
            "main",
            &times[..1],
            3,
            dir.path(),
        )
        .unwrap();
        assert!(!other[0].reused);
        let files = std::fs::read_dir(dir.path()).unwrap().count();
        assert_eq!(files, 9, "three EXR files, their times and their noise");
    }

    /// Relative luminance RMS of `a - b` against `b`'s mean, and the
    /// standard error of that estimate from the spread of the pixels'
    /// squared differences (the RMS's relative error is half the mean
    /// square's).
    fn lrms_with_error(a: &[Vec3], b: &[Vec3]) -> (f64, f64) {
        let y = crate::eval::metrics::luminance;
        let sq: Vec<f64> = a
            .iter()
            .zip(b)
            .map(|(&a, &b)| (y(a) - y(b)).powi(2))
            .collect();
        let n = sq.len() as f64;
        let m = sq.iter().sum::<f64>() / n;
        let var = sq.iter().map(|s| (s - m).powi(2)).sum::<f64>() / (n - 1.0);
        let mean_b = b.iter().map(|&c| y(c)).sum::<f64>() / n;
        let lrms = m.sqrt() / mean_b;
        (lrms, lrms * 0.5 * (var / n).sqrt() / m)
    }

    /// The noise a reference reports is the error it shows against a
    /// far better converged render: with 16 samples against 256 (whose
    /// own noise is a quarter of it), about √(1 + 1/16) times the noise.
    #[test]
    fn reference_noise_is_its_error_against_a_converged_render() {
        let scene = Scene::load(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/cornell-box/scene.toml"
        ))
        .unwrap();
        // Looking down at the boxes, the light out of view: the few pixels
        // on its rim would carry most of the squared error and leave the
        // estimates no error bars worth the name.
        let camera = crate::scene::CameraDesc {
            name: "boxes".into(),
            position: Vec3::new(278.0, 273.0, -800.0),
            direction: Vec3::new(0.0, -0.35, 1.0).normalize(),
            up: Vec3::Y,
            vfov_deg: 25.0,
        }
        .perspective(48, 48)
        .unwrap();
        let mut engine = accel::build(Backend::Bvh, &scene.geometry(), &scene.at(0.5)).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let reference = references(
            &scene,
            engine.as_mut(),
            &camera,
            "boxes",
            &[0.5],
            16,
            dir.path(),
        )
        .unwrap();
        let noise = reference[0].noise.unwrap();
        let (fine, _) = path_trace(&scene, engine.as_mut(), &camera, 0.5, 256, 99).unwrap();
        let (measured, measured_se) = lrms_with_error(&reference[0].radiance, &fine);
        // The estimate's own error bar, from the halves it was made of.
        let (a, _) = path_trace(&scene, engine.as_mut(), &camera, 0.5, 8, REFERENCE_SEED).unwrap();
        let (b, _) =
            path_trace(&scene, engine.as_mut(), &camera, 0.5, 8, REFERENCE_SEED_2).unwrap();
        let (halves, halves_se) = lrms_with_error(&a, &b);
        let expected = noise * (1.0f64 + 1.0 / 16.0).sqrt();
        let bar = 4.0 * (measured_se.powi(2) + (expected * halves_se / halves).powi(2)).sqrt();
        assert!(
            (measured - expected).abs() < bar,
            "16-spp reference: noise {noise:.4} predicts {expected:.4} against 256 spp, \
             measured {measured:.4} (four standard errors: {bar:.4})"
        );
    }
}
