//! Re-shading a synthesized frame at its own time. Reprojection moves
//! surfaces with their objects, but what lights them was baked at the base
//! times: a shadow that moves over a static floor would cross-fade. Here
//! the diffuse-lobe direct light of every pixel (what the bake stored as
//! `diffuse_direct`) is replaced by light samples with shadow rays against
//! the scene posed at the frame's time; mirrors, whose radiance belongs to
//! the base's direction and not the frame's, are traced again and what
//! they reflect is looked up in the bases.

use std::sync::Arc;

use anyhow::Result;
use glam::Vec3;
use rayon::prelude::*;

use super::base::Base;
use super::warp::{Accum, SKY_Z};
use super::Options;
use crate::accel::RayEngine;
use crate::image::RangeImage;
use crate::render::surface::{Reflected, SurfacePoint, SurfaceShading};
use crate::scene::Scene;

/// Re-shades `image` (made from `pixels`); `engine` holds the scene posed
/// at `t`. Returns the number of mirror pixels whose reflection no base
/// showed (they keep their projected radiance).
#[allow(clippy::too_many_arguments)]
pub fn apply(
    scene: &Scene,
    engine: &dyn RayEngine,
    t: f32,
    bases: &[Arc<Base>],
    weights: &[f32],
    pixels: &[Accum],
    opts: &Options,
    image: &mut RangeImage,
) -> Result<usize> {
    let shading = SurfaceShading::new(scene, engine, t);
    let w = image.width as usize;
    let cam = image.meta.camera.position;
    let poses_t = scene.at(t);
    // Per base: the motion from the frame's time back to the base's.
    let back: Vec<Vec<glam::Affine3A>> = bases
        .iter()
        .map(|b| {
            scene
                .objects
                .iter()
                .zip(&poses_t)
                .map(|(o, now)| o.motion.pose(b.time) * now.inverse())
                .collect()
        })
        .collect();
    let misses = image
        .radiance
        .par_chunks_mut(w)
        .zip(pixels.par_chunks(w))
        .enumerate()
        .map(|(y, (row, acc))| -> Result<usize> {
            let mut points = Vec::with_capacity(w);
            let mut at = Vec::with_capacity(w);
            let mut misses = 0;
            for (x, a) in acc.iter().enumerate() {
                if a.is_empty() || a.z >= SKY_Z {
                    continue;
                }
                let sp = SurfacePoint {
                    object: a.object,
                    primitive: a.primitive,
                    position: a.point,
                    wo: (cam - a.point).normalize_or_zero(),
                };
                if let Some((reflectance, reflected)) = shading.mirror(&sp) {
                    let seen = match reflected {
                        Reflected::Sky(l) => Some(l),
                        Reflected::Surface { hit, position } => {
                            gather(bases, weights, &back, hit.object, position, opts.tolerance)
                        }
                    };
                    match seen {
                        Some(l) => row[x] = shading.emission(&sp) + reflectance * l,
                        None => misses += 1,
                    }
                    continue;
                }
                points.push(sp);
                at.push(x);
            }
            let first = (y * w) as u64;
            let direct = shading.diffuse_direct(&points, opts.reshade_samples, opts.seed, first)?;
            for (x, d) in at.into_iter().zip(direct) {
                let a = &acc[x];
                let kept = (a.radiance - a.diffuse_direct) / a.w;
                row[x] = kept.max(Vec3::ZERO) + d;
            }
            Ok(misses)
        })
        .collect::<Result<Vec<usize>>>()?;
    Ok(misses.into_iter().sum())
}

/// Radiance of the surface point `p` of `object` (at the frame's time) as
/// the bases saw it, weighted as their passes are; `None` where no base
/// saw that point (another surface, or nothing, at its pixel).
fn gather(
    bases: &[Arc<Base>],
    weights: &[f32],
    back: &[Vec<glam::Affine3A>],
    object: u32,
    p: Vec3,
    tolerance: f32,
) -> Option<Vec3> {
    let (mut sum, mut total) = (Vec3::ZERO, 0.0);
    for ((b, &wt), back) in bases.iter().zip(weights).zip(back) {
        let q = back[object as usize].transform_point3(p);
        let Some(px) = b.camera.project(q) else {
            continue;
        };
        let (x, y) = (
            (px.x as u32).min(b.width() - 1),
            (px.y as u32).min(b.height() - 1),
        );
        let k = (y * b.width() + x) as usize;
        if b.object[k] != object {
            continue;
        }
        let (d, seen) = (
            q.distance(b.camera.position),
            b.points[k].distance(b.camera.position),
        );
        if (d - seen).abs() <= 2.0 * tolerance * d {
            let wt = wt.max(1e-3);
            sum += b.radiance_at(k) * wt;
            total += wt;
        }
    }
    (total > 0.0).then(|| sum / total)
}
