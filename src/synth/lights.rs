//! Lights' pixels, traced again at the frame's own pixels.
//!
//! A reprojected base pixel is one sample: where a light meets the dark
//! ceiling around it, a frame pixel shows all of one side or all of the
//! other, while a camera (and the reference) sees the fraction of the pixel
//! each covers. With bases no finer than the frame no blend of base pixels
//! recovers that fraction, and at a light forty times brighter than its
//! surroundings those few pixels outweigh every other error in the frame;
//! the base pixels at a light's rim, themselves such mixtures, are also
//! splatted over the light's inside and darken it. Primary rays through
//! the pixels at and beside a light find what each covers: a ray on the
//! light takes its emission (or the light's own pixels where they are not
//! darker), a ray beside it the frame's radiance at the nearest pixel that
//! shows the same face and holds no part of a light. No light is
//! computed anew, and nothing changes away from lights.

use std::ops::Range;

use glam::Vec3;
use rayon::prelude::*;

use crate::accel::{Hit, RayEngine};
use crate::image::{RangeImage, NO_HIT};
use crate::ray::Ray;
use crate::render::surface::{SurfacePoint, SurfaceShading};
use crate::scene::Scene;

/// Cosine of the largest angle between the normals of one face's pixels.
const FACE_COS: f32 = 0.9;

/// How far (in pixels) a ray looks for a pixel showing the surface it hit.
const REACH: i64 = 2;

/// Replaces the radiance of every frame pixel at or beside a light by the
/// mean of `side²` rays through it; `engine` holds the scene posed at
/// `t`. Rays through the pixel's four corners go first: an outline that
/// crosses the pixel crosses its sides, so where they all meet one surface
/// (a light's inside) the ray through its centre is enough, and the full
/// set is spent on the rim. Returns the number of pixels traced.
pub fn trace(
    scene: &Scene,
    engine: &dyn RayEngine,
    t: f32,
    side: u32,
    image: &mut RangeImage,
) -> usize {
    if side == 0 {
        return 0;
    }
    let (w, h) = (image.width as usize, image.height as usize);
    let ids = &image.object_id;
    let radiance = &image.radiance;
    let emissive = emissive(scene);
    let emits = |id: u32| emissive.get(id as usize).copied().unwrap_or(false);
    let on_light = light_pixels(&emissive, ids);
    let (lit, interior, window) = near_lights(&on_light, ids, w, h);
    let traced: Vec<usize> = window.into_par_iter().filter(|&k| lit[k]).collect();
    let shading = SurfaceShading::new(scene, engine, t);
    let camera = image.meta.camera;
    let around = Around {
        ids,
        interior: &interior,
        lit: &lit,
        normal: &image.normal,
        radiance,
        w: w as i64,
        h: h as i64,
    };
    let corners = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)];
    let full = hammersley(side * side);
    // Rays through pixel `k` at `offsets` and what they hit; `None` where
    // part of the pixel lies outside a fisheye's circle.
    let rays_through = |k: usize, offsets: &[(f32, f32)]| -> Option<(Vec<Ray>, Vec<Option<Hit>>)> {
        let (x, y) = ((k % w) as f32, (k / w) as f32);
        let rays: Vec<Ray> = offsets
            .iter()
            .map(|&(dx, dy)| camera.ray(x + dx, y + dy))
            .collect::<Option<_>>()?;
        let mut hits = vec![None; rays.len()];
        engine.intersect_batch(&rays, &mut hits);
        Some((rays, hits))
    };
    // Mean radiance of those rays.
    let shade = |k: usize, offsets: &[(f32, f32)], rays: &[Ray], hits: &[Option<Hit>]| -> Vec3 {
        let (x, y) = ((k % w) as f32, (k / w) as f32);
        let mut sum = Vec3::ZERO;
        for ((&(dx, dy), ray), hit) in offsets.iter().zip(rays).zip(hits) {
            let (sx, sy) = (x + dx, y + dy);
            sum += match hit {
                Some(hit) if emits(hit.object) => {
                    // A surface is never darker than its emission: a
                    // light's pixel that is holds a mixture with its dark
                    // surroundings, and the emission stands in.
                    let e = shading.emission(&SurfacePoint {
                        object: hit.object,
                        primitive: hit.primitive,
                        position: ray.at(hit.t),
                        wo: -ray.dir,
                    });
                    around
                        .nearest(hit.object, hit.normal, sx, sy, true)
                        .filter(|&c| luminance(c) >= luminance(e))
                        .unwrap_or(e)
                }
                Some(hit) => around
                    .nearest(hit.object, hit.normal, sx, sy, false)
                    .unwrap_or(radiance[k]),
                None => around
                    .nearest(NO_HIT, Vec3::ZERO, sx, sy, false)
                    .unwrap_or(radiance[k]),
            };
        }
        sum / rays.len() as f32
    };
    let values: Vec<(usize, Vec3)> = traced
        .par_iter()
        .filter_map(|&k| {
            // The corners only tell whether the pixel shows one surface.
            let (_, hits) = rays_through(k, &corners)?;
            let object = |hit: &Option<Hit>| hit.map_or(NO_HIT, |h| h.object);
            let one = hits.iter().all(|hit| object(hit) == object(&hits[0]));
            let offsets: &[(f32, f32)] = if one { &[(0.5, 0.5)] } else { &full };
            let (rays, hits) = rays_through(k, offsets)?;
            Some((k, shade(k, offsets, &rays, &hits)))
        })
        .collect();
    let count = values.len();
    for (k, c) in values {
        image.radiance[k] = c;
    }
    count
}

/// Gives base pixels beside a light the radiance of their own surface
/// away from it; returns how many changed.
///
/// A base pixel's radiance is the mean over its area, its point the one
/// its centre ray meets. Beside a light the mean holds part of the light,
/// and reprojection carries it to wherever that point lands in the frame:
/// with parallax, on a wall away from the frame's own view of the light,
/// where [`trace`] (which mends the frame's pixels at and beside lights)
/// does not reach. Such a pixel takes the nearest pixel within [`REACH`]
/// of the same object and face that no light touches; a pixel without
/// one keeps its value.
pub fn unmix_beside_lights(scene: &Scene, image: &mut RangeImage) -> usize {
    let (w, h) = (image.width as usize, image.height as usize);
    let emissive = emissive(scene);
    let ids = &image.object_id;
    let on_light = light_pixels(&emissive, ids);
    if !on_light.contains(&true) {
        return 0;
    }
    let (lit, interior, _) = near_lights(&on_light, ids, w, h);
    let around = Around {
        ids,
        interior: &interior,
        lit: &lit,
        normal: &image.normal,
        radiance: &image.radiance,
        w: w as i64,
        h: h as i64,
    };
    let values: Vec<(usize, Vec3)> = (0..ids.len())
        .into_par_iter()
        .filter(|&k| lit[k] && !on_light[k] && ids[k] != NO_HIT)
        .filter_map(|k| {
            let (sx, sy) = ((k % w) as f32 + 0.5, (k / w) as f32 + 0.5);
            let normal = image.normal[k];
            let j = around.best(ids[k], normal, sx, sy, |j| {
                !lit[j] && image.normal[j].dot(normal).abs() >= FACE_COS
            })?;
            Some((k, image.radiance[j]))
        })
        .collect();
    let count = values.len();
    for (k, c) in values {
        image.radiance[k] = c;
    }
    count
}

/// Rows beyond the lights' that [`near_lights`] works out. [`Around`]
/// reads rows up to [`REACH`] from a ray through a pixel beside a light (a
/// row from the light; a corner ray may fall on the next row), and a
/// pixel's interior depends on the ids up to two rows away: `REACH` + 4
/// rows would do (the test of `near_lights` finds one fewer short), and
/// two more are kept.
const WINDOW: usize = REACH as usize + 6;

/// Per pixel: whether it is at or beside a light (`on_light` grown by a
/// pixel), and whether its 3 × 3 neighbourhood is free of changes of
/// surface ([`interior`]). Both are worked out only in the rows within
/// [`WINDOW`] of a light (the pixels returned last), the only ones
/// [`Around`] reads: the whole frame took about as long as tracing the
/// lights' rims.
fn near_lights(
    on_light: &[bool],
    ids: &[u32],
    w: usize,
    h: usize,
) -> (Vec<bool>, Vec<bool>, Range<usize>) {
    let (mut lit, mut interior) = (vec![false; ids.len()], vec![false; ids.len()]);
    let rows = || on_light.par_chunks(w.max(1)).map(|r| r.contains(&true));
    let (Some(first), Some(last)) = (rows().position_first(|l| l), rows().position_last(|l| l))
    else {
        return (lit, interior, 0..0);
    };
    let (a, b) = (first.saturating_sub(WINDOW), (last + 1 + WINDOW).min(h));
    let window = a * w..b * w;
    lit[window.clone()].copy_from_slice(&dilate(&on_light[window.clone()], w, b - a));
    interior[window.clone()].copy_from_slice(&self::interior(&ids[window.clone()], w, b - a));
    (lit, interior, window)
}

/// Per pixel: whether it shows an object that `emissive` marks.
fn light_pixels(emissive: &[bool], ids: &[u32]) -> Vec<bool> {
    ids.par_iter()
        .map(|&id| emissive.get(id as usize).copied().unwrap_or(false))
        .collect()
}

/// Per pixel: whether its 3×3 neighbourhood is free of changes of
/// surface, so that its value cannot mix two surfaces.
fn interior(ids: &[u32], w: usize, h: usize) -> Vec<bool> {
    // Pixels on either side of a change of surface, and their 3×3
    // neighbourhoods: every pixel whose neighbours do not all show its own
    // surface lies in them (and a few more, a pixel from such a change).
    let touched: Vec<bool> = (0..ids.len())
        .into_par_iter()
        .map(|k| {
            let (x, y) = (k % w, k / w);
            (x + 1 < w && ids[k] != ids[k + 1])
                || (x > 0 && ids[k] != ids[k - 1])
                || (y + 1 < h && ids[k] != ids[k + w])
                || (y > 0 && ids[k] != ids[k - w])
        })
        .collect();
    dilate(&touched, w, h).into_iter().map(|e| !e).collect()
}

/// Per object: whether it emits light.
pub(super) fn emissive(scene: &Scene) -> Vec<bool> {
    (0..scene.objects.len() as u32)
        .map(|o| scene.material_of(o).emission.is_some())
        .collect()
}

/// Whether any pixel of `image` shows a light: a frame without one needs
/// no ray engine for [`trace`].
pub fn shows_a_light(scene: &Scene, image: &RangeImage) -> bool {
    let emissive = emissive(scene);
    image
        .object_id
        .par_iter()
        .any(|&id| emissive.get(id as usize).copied().unwrap_or(false))
}

/// `mask` grown by one pixel in every direction (a 3×3 dilation), in two
/// passes of one row and one column.
fn dilate(mask: &[bool], w: usize, h: usize) -> Vec<bool> {
    let mut rows = vec![false; mask.len()];
    rows.par_chunks_mut(w)
        .zip(mask.par_chunks(w))
        .for_each(|(out, row)| {
            for x in 0..w {
                out[x] = row[x.saturating_sub(1)] || row[x] || row[(x + 1).min(w - 1)];
            }
        });
    let mut out = vec![false; mask.len()];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let (above, below) = (y.saturating_sub(1) * w, (y + 1).min(h - 1) * w);
        for x in 0..w {
            row[x] = rows[above + x] || rows[y * w + x] || rows[below + x];
        }
    });
    out
}

/// The frame's pixels, for looking up what a traced ray saw.
struct Around<'a> {
    ids: &'a [u32],
    /// Whether a pixel's neighbours all show its surface.
    interior: &'a [bool],
    /// Whether a pixel is at or beside a light: its value may hold part
    /// of it.
    lit: &'a [bool],
    normal: &'a [Vec3],
    radiance: &'a [Vec3],
    w: i64,
    h: i64,
}

impl Around<'_> {
    /// Radiance of the pixel nearest `(sx, sy)` within [`REACH`] that shows
    /// `object`, preferring pixels of the same face (normal within 25° of
    /// `normal`; one object may be a box lit on one side) and then pixels
    /// whose values cannot be mixtures (away from lights, then inside a
    /// surface);
    /// with `inside_only`, only pixels inside a surface.
    fn nearest(
        &self,
        object: u32,
        normal: Vec3,
        sx: f32,
        sy: f32,
        inside_only: bool,
    ) -> Option<Vec3> {
        self.best(object, normal, sx, sy, |j| !inside_only || self.interior[j])
            .map(|j| self.radiance[j])
    }

    /// The pixel [`Around::nearest`] prefers among those `accept` allows.
    fn best(
        &self,
        object: u32,
        normal: Vec3,
        sx: f32,
        sy: f32,
        accept: impl Fn(usize) -> bool,
    ) -> Option<usize> {
        let (cx, cy) = (sx.floor() as i64, sy.floor() as i64);
        let mut best: Option<((bool, bool, bool, f32), usize)> = None;
        for v in (cy - REACH).max(0)..=(cy + REACH).min(self.h - 1) {
            for u in (cx - REACH).max(0)..=(cx + REACH).min(self.w - 1) {
                let j = (v * self.w + u) as usize;
                if self.ids[j] != object || !accept(j) {
                    continue;
                }
                let d = (u as f32 + 0.5 - sx).powi(2) + (v as f32 + 0.5 - sy).powi(2);
                let other_face = self.normal[j].dot(normal).abs() < FACE_COS;
                let key = (other_face, self.lit[j], !self.interior[j], d);
                if best.is_none_or(|(b, _)| key < b) {
                    best = Some((key, j));
                }
            }
        }
        best.map(|(_, j)| j)
    }
}

pub(super) fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// `n` points of the Hammersley set in the unit square: stratified in x,
/// van der Corput in y, so a straight edge in any direction splits them
/// close to its area (a regular grid of the same size resolves an edge
/// along its rows only to `1/√n`).
fn hammersley(n: u32) -> Vec<(f32, f32)> {
    (0..n)
        .map(|i| {
            let y = (i.reverse_bits() as f64 / 2f64.powi(32)) as f32 + 0.5 / n as f32;
            ((i as f32 + 0.5) / n as f32, y.fract())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Camera, Projection};
    use crate::image::RangeMeta;

    #[test]
    fn masks_near_lights_are_those_of_the_whole_frame_where_they_are_read() {
        let (w, h) = (37, 41);
        // Rows a ray through a pixel beside the light (rows 17..=20) looks
        // up.
        let read = (17 - 1 - REACH as usize) * w..(20 + 2 + REACH as usize + 1) * w;
        // Two surfaces meeting along each row's edge in turn (and a light,
        // id 9), so that some edge lies just outside the rows worked out.
        for edge in 0..h {
            let ids: Vec<u32> = (0..w * h)
                .map(|k| {
                    let (x, y) = (k % w, k / w);
                    if (17..=20).contains(&y) && (10..14).contains(&x) {
                        9
                    } else {
                        (y > edge) as u32
                    }
                })
                .collect();
            let on_light: Vec<bool> = ids.iter().map(|&i| i == 9).collect();
            let (lit, interior, window) = near_lights(&on_light, &ids, w, h);
            assert!(window.start <= read.start && window.end >= read.end);
            assert_eq!(lit, dilate(&on_light, w, h), "edge after row {edge}");
            let whole = self::interior(&ids, w, h);
            assert_eq!(
                interior[read.clone()],
                whole[read.clone()],
                "edge after row {edge}"
            );
        }
        // Without a light nothing is worked out.
        let ids = vec![0; w * h];
        let none = vec![false; w * h];
        assert_eq!(near_lights(&none, &ids, w, h), (none.clone(), none, 0..0));
    }

    /// An 8×8 view of the Cornell box's ceiling (radiance 1) with the light
    /// (40) on a 2×2 square in the middle; the ring of pixels around the
    /// light holds a mixture of both (10).
    fn ceiling_with_a_light(scene: &Scene) -> RangeImage {
        let id = |name: &str| scene.objects.iter().position(|o| o.name == name).unwrap() as u32;
        let camera = Camera::looking(
            Vec3::ZERO,
            Vec3::Y,
            Vec3::Z,
            Projection::Perspective { vfov_deg: 40.0 },
            8,
            8,
        )
        .unwrap();
        let mut image = RangeImage::empty(RangeMeta {
            camera,
            time: 0.0,
            scene: String::new(),
        });
        for k in 0..64 {
            let (x, y) = (k % 8, k / 8);
            let (on, beside) = (
                (3..5).contains(&x) && (3..5).contains(&y),
                (2..6).contains(&x) && (2..6).contains(&y),
            );
            image.object_id[k] = id(if on { "light" } else { "ceiling" });
            image.normal[k] = -Vec3::Y;
            image.distance[k] = 1.0;
            image.radiance[k] = Vec3::splat(if on {
                40.0
            } else if beside {
                10.0
            } else {
                1.0
            });
        }
        image
    }

    #[test]
    fn base_pixels_beside_a_light_take_their_surface_away_from_it() {
        let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("scenes/cornell-box/scene.toml");
        let scene = Scene::load(&path).unwrap();
        let mut image = ceiling_with_a_light(&scene);
        let before = image.clone();
        assert_eq!(unmix_beside_lights(&scene, &mut image), 12);
        for k in 0..64 {
            let want = if before.radiance[k].x == 10.0 {
                1.0
            } else {
                before.radiance[k].x
            };
            assert_eq!(image.radiance[k], Vec3::splat(want), "pixel {k}");
        }

        // A pixel of another object, or of another face of its own, with
        // no clean pixel of its face within reach keeps its value.
        let mut image = ceiling_with_a_light(&scene);
        let back = scene.objects.iter().position(|o| o.name == "back").unwrap() as u32;
        image.object_id[2 * 8 + 2] = back;
        image.normal[5 * 8 + 5] = Vec3::Z;
        assert_eq!(unmix_beside_lights(&scene, &mut image), 10);
        assert_eq!(image.radiance[2 * 8 + 2], Vec3::splat(10.0));
        assert_eq!(image.radiance[5 * 8 + 5], Vec3::splat(10.0));

        // Nothing changes where no light is in view.
        let mut image = ceiling_with_a_light(&scene);
        let ceiling = image.object_id[0];
        for id in image.object_id.iter_mut() {
            *id = ceiling;
        }
        let before = image.clone();
        assert_eq!(unmix_beside_lights(&scene, &mut image), 0);
        assert_eq!(image.radiance, before.radiance);
    }
}
