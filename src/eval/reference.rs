//! Converged path-traced references, cached as range images so that a
//! rerun of an experiment (another quality, another renderer setting) does
//! not pay for them again.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use glam::Vec3;

use crate::accel::InstancedEngine;
use crate::camera::Camera;
use crate::image;
use crate::render::{self, RenderSettings};
use crate::scene::hash::ContentHash;
use crate::scene::Scene;

/// Seed of every reference; test renders use other seeds so that their
/// noise is independent of the reference's (the same seed would replay the
/// reference's first samples and understate the error).
pub const REFERENCE_SEED: u64 = 0;

/// One reference frame.
#[derive(Clone, Debug)]
pub struct Reference {
    pub radiance: Vec<Vec3>,
    /// Path-tracing time; unknown for a cache entry from before times were
    /// recorded beside it.
    pub seconds: Option<f64>,
    /// Whether it came from the cache.
    pub reused: bool,
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
        if let Some(radiance) = cached(&path, camera, t) {
            let seconds = std::fs::read_to_string(&seconds_path)
                .ok()
                .and_then(|s| s.trim().parse().ok());
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
        let (img, seconds) = path_trace_image(scene, engine, camera, t, spp, REFERENCE_SEED)?;
        image::write_exr(&path, &img)?;
        std::fs::write(&seconds_path, format!("{seconds}\n"))
            .with_context(|| format!("writing {}", seconds_path.display()))?;
        out.push(Reference {
            radiance: img.radiance,
            seconds: Some(seconds),
            reused: false,
        });
    }
    Ok(out)
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
        assert!(first.iter().all(|r| !r.reused && r.seconds.is_some()));
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
        assert_eq!(files, 6, "three EXR files and their times");
    }
}
