//! Visibility from the view space (paper §4.3, first method): rays shot
//! over a wide angle from random viewpoints at random times, hits counted
//! per object.

use std::f32::consts::PI;

use anyhow::{Context, Result};
use glam::Vec3;
use rayon::prelude::*;

use super::params::{TRIALS, VIEWS_PER_TRIAL};
use crate::accel::{InstancedEngine, RayEngine};
use crate::ray::Ray;
use crate::rng::{SplitMix64, GOLDEN};
use crate::scene::{Scene, ViewSpace};

/// Half-angle of the cone of rays around a camera's direction when the
/// scene has no view space: a wide-angle lens, since the viewer may turn.
const CAMERA_CONE_DEG: f32 = 60.0;

/// Fixed seed: the simplification is a pure function of scene and quality.
const SEED: u64 = 0x5eed_0403;

/// Hits per object and the number of rays traced.
pub struct HitCounts {
    pub hits: Vec<u64>,
    pub rays: u64,
}

/// Where rays start and which way they go.
enum Viewer<'a> {
    Space(ViewSpace),
    Cameras(&'a [crate::scene::CameraDesc]),
}

/// Counts hits per object for about `rays` rays. `None` when the scene gives
/// nowhere to look from (no view space and no camera).
pub fn count_hits(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    rays: u64,
) -> Result<Option<HitCounts>> {
    let viewer = match (scene.view_space, scene.cameras.as_slice()) {
        (Some(v), _) => Viewer::Space(v),
        (None, []) => return Ok(None),
        (None, cams) => Viewer::Cameras(cams),
    };
    let anim = scene.animation;
    let trials = if scene.is_static() { 1 } else { TRIALS };
    let views = TRIALS * VIEWS_PER_TRIAL / trials;
    let per_view = rays.div_ceil((trials * views) as u64).max(1);
    let mut hits = vec![0u64; scene.objects.len()];
    for trial in 0..trials {
        let mut rng = Rng::new(SEED, trial as u64);
        let t = if trials == 1 {
            anim.start
        } else {
            anim.start + rng.next() * (anim.end - anim.start)
        };
        engine
            .set_transforms(&scene.at(t))
            .with_context(|| format!("{}: posing the scene at t = {t}", scene.source.display()))?;
        let eng: &dyn RayEngine = &*engine;
        let counts = (0..views)
            .into_par_iter()
            .map(|v| {
                let view = (trial * views + v) as u64;
                let mut rng = Rng::new(SEED ^ 0xa5a5, view);
                let (origin, axis, cos_max) = match &viewer {
                    Viewer::Space(s) => (s.sample(|| rng.next()), Vec3::Z, -1.0),
                    Viewer::Cameras(c) => {
                        let cam = &c[view as usize % c.len()];
                        (
                            cam.position,
                            cam.direction,
                            CAMERA_CONE_DEG.to_radians().cos(),
                        )
                    }
                };
                let rays: Vec<Ray> = (0..per_view)
                    .map(|_| Ray::new(origin, cone_dir(axis, cos_max, &mut rng)))
                    .collect();
                let mut out = vec![None; rays.len()];
                eng.intersect_batch(&rays, &mut out);
                let mut local = vec![0u64; hits.len()];
                for h in out.into_iter().flatten() {
                    local[h.object as usize] += 1;
                }
                local
            })
            .reduce(
                || vec![0u64; hits.len()],
                |mut a, b| {
                    a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                    a
                },
            );
        hits.iter_mut().zip(counts).for_each(|(x, y)| *x += y);
    }
    Ok(Some(HitCounts {
        hits,
        rays: per_view * (trials * views) as u64,
    }))
}

/// A uniform direction in the cone `dot(d, axis) >= cos_max` (the whole
/// sphere for `cos_max = -1`).
fn cone_dir(axis: Vec3, cos_max: f32, rng: &mut Rng) -> Vec3 {
    let cos = 1.0 - rng.next() * (1.0 - cos_max);
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let phi = 2.0 * PI * rng.next();
    let (u, v) = axis.any_orthonormal_pair();
    u * (sin * phi.cos()) + v * (sin * phi.sin()) + axis * cos
}

/// SplitMix64: tiny, and one stream per (seed, view) keeps counts
/// independent of the thread that traces a view.
struct Rng(SplitMix64);

impl Rng {
    fn new(seed: u64, stream: u64) -> Rng {
        let mut r = SplitMix64::new(seed ^ stream.wrapping_mul(GOLDEN));
        r.next_u64();
        Rng(r)
    }

    /// Uniform in `[0, 1)`.
    fn next(&mut self) -> f32 {
        self.0.next_f32()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cone_directions_are_unit_and_inside_the_cone() {
        let mut rng = Rng::new(1, 2);
        let axis = Vec3::new(0.3, -0.2, 0.9).normalize();
        let cos_max = 0.5;
        let mut mean = Vec3::ZERO;
        for _ in 0..10_000 {
            let d = cone_dir(axis, cos_max, &mut rng);
            assert!((d.length() - 1.0).abs() < 1e-5);
            assert!(d.dot(axis) >= cos_max - 1e-6);
            mean += d;
        }
        // Uniform in the cone: the mean points along the axis with length
        // (1 + cos_max) / 2.
        let mean = mean / 10_000.0;
        assert!((mean.dot(axis) - 0.75).abs() < 0.01, "{mean}");
        assert!(mean.cross(axis).length() < 0.02, "{mean}");
    }
}
