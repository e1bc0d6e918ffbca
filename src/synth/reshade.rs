//! Re-shading a synthesized frame at its own time. Reprojection moves
//! surfaces with their objects, but what lights them was baked at the base
//! times: a shadow that moves over a static floor would cross-fade. Here
//! the diffuse-lobe direct light of every pixel (what the bake stored as
//! `diffuse_direct`) is corrected by the change light samples with shadow
//! rays find between the base times and the frame's; mirrors, whose
//! radiance belongs to the base's direction and not the frame's, are traced
//! again from where the frame's own rays meet them, and what they reflect
//! is looked up in the bases (a light: never darker than its emission).
//!
//! The correction is a control variate: each pixel draws the same light
//! samples at the frame's time and at every base time, so where nothing
//! between the point and the light moved the two estimates are equal and
//! the pixel keeps the bases' light, with the bases' samples per pixel
//! (a frame's few samples would otherwise replace it with their noise);
//! only where a shadow moved does the difference count.

use std::f32::consts::FRAC_1_PI;
use std::sync::Arc;

use anyhow::Result;
use glam::{Affine3A, Vec3};
use rayon::prelude::*;

use super::base::Base;
use super::indirect::Records;
use super::lights::luminance;
use super::warp::{Accum, SKY_Z};
use super::Options;
use crate::accel::RayEngine;
use crate::camera::Camera;
use crate::image::RangeImage;
use crate::render::surface::{Reflected, SurfacePoint, SurfaceShading};
use crate::scene::{Bsdf, Scene};

/// Light samples every frame pixel takes at the frame's time and at each
/// base time to find whether its light changed. Where it did not, the
/// correction is zero whatever the count; where it did, these few would
/// leave salt and pepper in a moved shadow (one sample a subpixel lit or
/// not), so those pixels take all of `reshade_samples`.
pub const FIND_SAMPLES: u32 = 4;

/// Per object: the motion from the frame's time `t` back to `then`.
fn motions_back(scene: &Scene, t: f32, then: f32) -> Vec<Affine3A> {
    scene
        .objects
        .iter()
        .zip(scene.at(t))
        .map(|(o, now)| o.motion.pose(then) * now.inverse())
        .collect()
}

/// The surface point a frame pixel shows, moved from the frame's time by
/// `back` (`None`: at the frame's time); `None` where it shows nothing.
fn surface_point(a: &Accum, cam: Vec3, back: Option<&[Affine3A]>) -> Option<SurfacePoint> {
    if a.is_empty() || a.z >= SKY_Z {
        return None;
    }
    let wo = (cam - a.point).normalize_or_zero();
    let (position, wo) = match back.and_then(|b| b.get(a.object as usize)) {
        Some(m) => (
            m.transform_point3(a.point),
            m.transform_vector3(wo).normalize_or_zero(),
        ),
        None => (a.point, wo),
    };
    Some(SurfacePoint {
        object: a.object,
        primitive: a.primitive,
        position,
        wo,
    })
}

/// Where the frame's own ray through pixel (`x`, `y`) meets the mirror
/// `sp` lies on. A pixel's point is its heaviest sample's, up to half a
/// base pixel from the pixel's ray: on a diffuse surface that changes
/// little, but a mirror traced from there shows what the frame sees that
/// far off, and from bases coarser than the frame the reflection of a
/// light lands pixels away from where it belongs.
fn on_own_ray(
    engine: &dyn RayEngine,
    camera: &Camera,
    x: usize,
    y: usize,
    sp: SurfacePoint,
) -> SurfacePoint {
    let Some(ray) = camera.ray(x as f32 + 0.5, y as f32 + 0.5) else {
        return sp;
    };
    match engine.intersect(&ray) {
        Some(hit) if hit.object == sp.object => SurfacePoint {
            object: hit.object,
            primitive: hit.primitive,
            position: ray.at(hit.t),
            wo: -ray.dir.normalize_or_zero(),
        },
        _ => sp,
    }
}

/// The diffuse direct light of frame pixels at time `then` (their points
/// moved there with their objects; `then == t`: the frame's own time),
/// `samples` light samples each, drawn from each pixel's own sampler
/// stream so that every time draws the same ones; `engine` holds the scene
/// posed at `then`. Only the pixels `only` marks are shaded (all without
/// it); the others are left as `out` holds them.
#[allow(clippy::too_many_arguments)]
pub fn direct_at(
    scene: &Scene,
    engine: &dyn RayEngine,
    t: f32,
    then: f32,
    pixels: &[Accum],
    width: usize,
    cam: Vec3,
    samples: u32,
    seed: u64,
    only: Option<&[bool]>,
    out: &mut [Vec3],
) -> Result<()> {
    let shading = SurfaceShading::new(scene, engine, then);
    let back = motions_back(scene, t, then);
    out.par_chunks_mut(width)
        .zip(pixels.par_chunks(width))
        .enumerate()
        .try_for_each(|(y, (row, acc))| -> Result<()> {
            let (mut points, mut streams, mut at) = (Vec::new(), Vec::new(), Vec::new());
            for (x, a) in acc.iter().enumerate() {
                let k = y * width + x;
                if only.is_some_and(|o| !o[k]) || is_mirror(scene, a) {
                    continue;
                }
                if let Some(sp) = surface_point(a, cam, Some(&back)) {
                    points.push(sp);
                    streams.push(k as u64);
                    at.push(x);
                }
            }
            let direct = shading.diffuse_direct(&points, &streams, samples, seed)?;
            for (x, d) in at.into_iter().zip(direct) {
                row[x] = d;
            }
            Ok(())
        })
}

/// A frame-sized plane of light, allocated fallibly: one is kept for the
/// frame's time and one for each base time, which may be more than memory
/// holds.
pub fn light_plane(len: usize, width: usize, what: &str) -> Result<Vec<Vec3>> {
    let mut out = Vec::new();
    crate::alloc::resize(&mut out, len, Vec3::ZERO, || {
        format!(
            "re-shading a frame of {len} pixels ({width}x{}): the light at {what}",
            len / width.max(1)
        )
    })?;
    Ok(out)
}

fn is_mirror(scene: &Scene, a: &Accum) -> bool {
    !a.is_empty() && a.z < SKY_Z && matches!(scene.material_of(a.object).bsdf, Bsdf::Mirror { .. })
}

/// Which pixels' light changed between some base time and the frame's:
/// the few samples every pixel takes find where a shadow moved or a
/// surface turned, and only there do more samples pay. A pixel whose
/// samples all agreed may still lie in a penumbra that moved (its few
/// samples happened to miss the occluder at both times), so the pixels
/// within `reach` of a changed one are taken too: moved shadows are
/// contiguous, a changed pixel's neighbours are where the rest of it is.
/// A change below a hundredth of the light is rounding in a moved point,
/// not a moved shadow.
pub fn changed(now: &[Vec3], then: &[Vec<Vec3>], width: usize, reach: usize) -> Vec<bool> {
    let height = now.len() / width.max(1);
    let seed: Vec<bool> = (0..now.len())
        .into_par_iter()
        .map(|k| {
            let a = luminance(now[k]);
            then.iter().any(|th| {
                let b = luminance(th[k]);
                (a - b).abs() > 0.01 * a.max(b)
            })
        })
        .collect();
    // Dilated by rows, then by columns (a square of side 2 reach + 1).
    let mut rows = vec![false; now.len()];
    rows.par_chunks_mut(width)
        .zip(seed.par_chunks(width))
        .for_each(|(out, row)| {
            for (x, o) in out.iter_mut().enumerate() {
                let (a, b) = (x.saturating_sub(reach), (x + reach + 1).min(width));
                *o = row[a..b].iter().any(|&c| c);
            }
        });
    let mut out = vec![false; now.len()];
    out.par_chunks_mut(width).enumerate().for_each(|(y, o)| {
        let (a, b) = (y.saturating_sub(reach), (y + reach + 1).min(height));
        for (x, o) in o.iter_mut().enumerate() {
            *o = (a..b).any(|yy| rows[yy * width + x]);
        }
    });
    out
}

/// Where a pixel's blend's mean base time `tau` falls among the base
/// `times` (ascending): the two it lies between and the later one's
/// weight (the one nearest, twice, outside them), so that its light there
/// is its light at those times interpolated linearly.
fn mean_time(times: &[f32], tau: f32) -> (usize, usize, f32) {
    let i = times.partition_point(|&s| s <= tau).clamp(1, times.len()) - 1;
    match times.get(i + 1) {
        Some(&next) => (
            i,
            i + 1,
            ((tau - times[i]) / (next - times[i])).clamp(0.0, 1.0),
        ),
        None => (i, i, 0.0),
    }
}

/// Re-shades `image` (made from `pixels`); `engine` holds the scene posed
/// at `t`, `now` is [`direct_at`] the frame's time and `then[i]` at base
/// time `times[i]`; `records`, where the bake has them and they change,
/// correct the diffuse indirect light too ([`super::indirect`]), once for
/// each `block` × `block` subpixels of one frame pixel that show one
/// triangle. Returns
/// the number of mirror pixels whose reflection no base showed (they keep
/// their projected radiance).
#[allow(clippy::too_many_arguments)]
pub fn apply(
    scene: &Scene,
    engine: &dyn RayEngine,
    t: f32,
    bases: &[Arc<Base>],
    weights: &[f32],
    pixels: &[Accum],
    times: &[f32],
    now: &[Vec3],
    then: &[Vec<Vec3>],
    records: Option<&Records>,
    block: usize,
    opts: &Options,
    image: &mut RangeImage,
) -> Result<usize> {
    let shading = SurfaceShading::new(scene, engine, t);
    let w = image.width as usize;
    let camera = image.meta.camera;
    let cam = camera.position;
    // Per base: the motion from the frame's time back to the base's.
    let back: Vec<Vec<Affine3A>> = bases
        .iter()
        .map(|b| motions_back(scene, t, b.time))
        .collect();
    // A frame pixel's k × k subpixels of one triangle and one blend of
    // base times share their indirect correction: records vary over many
    // pixels, and looking them up for every subpixel cost more than all
    // the rest of re-shading.
    let block = block.max(1);
    let misses = image
        .radiance
        .par_chunks_mut(w * block)
        .zip(pixels.par_chunks(w * block))
        .enumerate()
        .map(|(band, (rows, accs))| -> Result<usize> {
            let mut misses = 0;
            let mut shared: Vec<Option<(u32, u32, f32, Vec3)>> = vec![None; w.div_ceil(block)];
            for (dy, (row, acc)) in rows.chunks_mut(w).zip(accs.chunks(w)).enumerate() {
                let y = band * block + dy;
                for (x, a) in acc.iter().enumerate() {
                    let Some(mut sp) = surface_point(a, cam, None) else {
                        continue;
                    };
                    if matches!(scene.material_of(sp.object).bsdf, Bsdf::Mirror { .. }) {
                        sp = on_own_ray(engine, &camera, x, y, sp);
                    }
                    if let Some((reflectance, reflected)) = shading.mirror(&sp) {
                        let seen = match reflected {
                            Reflected::Sky(l) => Some(l),
                            Reflected::Surface { hit, position } => {
                                let seen = gather(
                                    bases,
                                    weights,
                                    &back,
                                    hit.object,
                                    position,
                                    opts.tolerance,
                                );
                                // A light small in the bases has few pixels
                                // that do not mix it with its dark surroundings;
                                // a surface is never darker than its emission,
                                // which stands in (as for lights seen directly).
                                let e = shading.emission(&SurfacePoint {
                                    object: hit.object,
                                    primitive: hit.primitive,
                                    position,
                                    wo: (sp.position - position).normalize_or_zero(),
                                });
                                match seen {
                                    Some(l) if luminance(l) >= luminance(e) => Some(l),
                                    _ if e != Vec3::ZERO => Some(e),
                                    other => other,
                                }
                            }
                        };
                        match seen {
                            Some(l) => row[x] = shading.emission(&sp) + reflectance * l,
                            None => misses += 1,
                        }
                        continue;
                    }
                    let k = y * w + x;
                    let tau = a.alpha / a.w;
                    let (i, j, f) = mean_time(times, tau);
                    let before = then[i][k].lerp(then[j][k], f);
                    let mut l = a.radiance / a.w + now[k] - before;
                    if let Some(r) = records {
                        let slot = &mut shared[x / block];
                        let correction = match *slot {
                            Some((o, p, t0, c))
                                if o == sp.object
                                    && p == sp.primitive
                                    && (t0 - tau).abs() <= 1e-3 =>
                            {
                                c
                            }
                            _ => {
                                let c = match shading.diffuse_query(&sp) {
                                    Some(q) => {
                                        let ei = r.irradiance(&q, times[i])?;
                                        let before = if j == i {
                                            ei
                                        } else {
                                            ei.lerp(r.irradiance(&q, times[j])?, f)
                                        };
                                        q.albedo * FRAC_1_PI * (r.irradiance(&q, t)? - before)
                                    }
                                    None => Vec3::ZERO,
                                };
                                *slot = Some((sp.object, sp.primitive, tau, c));
                                c
                            }
                        };
                        l += correction;
                    }
                    row[x] = l.max(Vec3::ZERO);
                }
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
    back: &[Vec<Affine3A>],
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
