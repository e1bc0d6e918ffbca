//! Lights' pixels and silhouettes, traced again at the frame's own
//! pixels.
//!
//! A reprojected base pixel is one sample: where a light meets the dark
//! ceiling around it, a frame pixel shows all of one side or all of the
//! other, while a camera (and the reference) sees the fraction of the pixel
//! each covers. With bases no finer than the frame no blend of base pixels
//! recovers that fraction, and at a light forty times brighter than its
//! surroundings those few pixels outweigh every other error in the frame;
//! the base pixels at a light's rim, themselves such mixtures, are also
//! splatted over the light's inside and darken it. Every silhouette has
//! the same fault at a smaller contrast: its outline follows the base's
//! pixel grid, turned and stretched by reprojection, as a jagged or dotted
//! edge, where a render's pixels hold each surface's share. Primary rays
//! through the pixels at and beside a light or a change of surface find
//! what each covers: a ray on a light takes its emission (or the light's
//! own pixels where they are not darker), any other ray the frame's
//! radiance at the nearest pixel that shows the same face and holds no
//! part of a light. No light is computed anew, and nothing changes inside
//! surfaces.

use std::ops::Range;

use glam::Vec3;
use rayon::prelude::*;

use crate::accel::{Hit, RayEngine};
use crate::image::{RangeImage, NO_HIT};
use crate::ray::Ray;
use crate::render::surface::{SurfacePoint, SurfaceShading};
use crate::rng::Pcg32;
use crate::scene::Scene;

/// Cosine of the largest angle between the normals of one face's pixels.
const FACE_COS: f32 = 0.9;

/// How far (in pixels) a ray looks for a pixel showing the surface it hit.
const REACH: i64 = 2;

/// Replaces the radiance of every frame pixel at or beside a light or a
/// silhouette against the sky by the mean of `side²` rays through it; `engine` holds the
/// scene posed at `t`. Rays through the pixel's four corners go first: an
/// outline that crosses the pixel crosses its sides, so where they all
/// meet the surface the pixel shows, and its value is that surface's alone
/// (`mixed`, per pixel, says where subpixels mixed objects), it keeps its
/// value; a light's inside, or a pixel that one surface covers but whose
/// value mixes, takes the ray through its centre; the full set is spent
/// on the rims. Returns the number of pixels traced.
pub fn trace(
    scene: &Scene,
    engine: &dyn RayEngine,
    t: f32,
    side: u32,
    mixed: Option<&[bool]>,
    image: &mut RangeImage,
) -> usize {
    if side == 0 || image.is_empty() {
        return 0;
    }
    let (w, h) = (image.width as usize, image.height as usize);
    let ids = &image.object_id;
    let radiance = &image.radiance;
    let emissive = emissive(scene);
    let emits = |id: u32| emissive.get(id as usize).copied().unwrap_or(false);
    let near = whole_frame(&emissive, ids, w, h);
    let sky: Vec<bool> = ids.par_iter().map(|&id| id == NO_HIT).collect();
    let beside_sky = dilate(&dilate(&sky, w, h), w, h);
    let shading = SurfaceShading::new(scene, engine, t);
    let camera = image.meta.camera;
    let around = Around {
        ids,
        near: &near,
        normal: &image.normal,
        radiance,
        w: w as i64,
        h: h as i64,
    };
    // Rows of the pixels to trace (those at or beside a light or a change
    // of surface within two pixels of the sky), and the columns in each.
    let first_row = 0;
    let rows: Vec<Vec<usize>> = (0..h)
        .into_par_iter()
        .map(|y| {
            (0..w)
                .filter(|&x| {
                    let k = y * w + x;
                    near.lit(k) || (!near.interior(k) && beside_sky[k])
                })
                .collect()
        })
        .collect();
    // What the ray through each pixel corner they need meets (`None`
    // outside a fisheye's circle), traced once for the pixels sharing it,
    // a row of corners at a time.
    let corner_rows: Vec<Vec<(usize, Option<u32>)>> = (0..=rows.len())
        .into_par_iter()
        .map(|r: usize| {
            let mut xs: Vec<usize> = [r.checked_sub(1), (r < rows.len()).then_some(r)]
                .into_iter()
                .flatten()
                .flat_map(|r| rows[r].iter().flat_map(|&x| [x, x + 1]))
                .collect();
            xs.sort_unstable();
            xs.dedup();
            let y = (first_row + r) as f32;
            let rays: Vec<Option<Ray>> = xs.iter().map(|&x| camera.ray(x as f32, y)).collect();
            let objects = objects_met(engine, &rays);
            xs.into_iter().zip(objects).collect()
        })
        .collect();
    let corner = |x: usize, r: usize| -> Option<u32> {
        let row = &corner_rows[r];
        row[row.binary_search_by_key(&x, |c| c.0).ok()?].1
    };
    let full = hammersley(side * side);
    // Mean radiance of the rays through pixel `k` at `offsets`.
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
    let centre = [(0.5, 0.5)];
    // Pixels (column, row of the window) in runs of a row, their rays
    // traced together: a rim's pixels crowd into few rows.
    let pixels: Vec<(usize, usize)> = rows
        .iter()
        .enumerate()
        .flat_map(|(r, xs)| xs.iter().map(move |&x| (x, r)))
        .collect();
    let values: Vec<(usize, Vec3)> = pixels
        .par_chunks(RUN)
        .flat_map_iter(|run| {
            // The corners only tell whether a pixel shows one surface: one
            // ray through its centre then, the full set on a rim. A pixel
            // partly outside a fisheye's circle is left as it is.
            let mut sets: [(Vec<usize>, Vec<Ray>); 2] = Default::default();
            for &(x, r) in run {
                let Some(c) = [(x, r), (x + 1, r), (x, r + 1), (x + 1, r + 1)]
                    .map(|(x, r)| corner(x, r))
                    .into_iter()
                    .collect::<Option<Vec<u32>>>()
                else {
                    continue;
                };
                let one = c.iter().all(|&o| o == c[0]);
                let y = first_row + r;
                let k = y * w + x;
                let mixes = mixed.is_some_and(|m| m[k]);
                if one && c[0] == ids[k] && !near.lit(k) && !mixes {
                    continue;
                }
                let shifted;
                let offsets: &[(f32, f32)] = if one {
                    &centre
                } else {
                    shifted = shift(&full, k);
                    &shifted
                };
                let Some(rays) = offsets
                    .iter()
                    .map(|&(dx, dy)| camera.ray(x as f32 + dx, y as f32 + dy))
                    .collect::<Option<Vec<Ray>>>()
                else {
                    continue;
                };
                let set = &mut sets[!one as usize];
                set.0.push(k);
                set.1.extend(rays);
            }
            let mut out = Vec::new();
            for (rim, (pixels, rays)) in sets.into_iter().enumerate() {
                let mut hits = vec![None; rays.len()];
                engine.intersect_batch(&rays, &mut hits);
                let n = if rim == 1 { full.len() } else { 1 };
                for (i, &k) in pixels.iter().enumerate() {
                    let span = i * n..(i + 1) * n;
                    let offsets = if rim == 1 {
                        shift(&full, k)
                    } else {
                        centre.to_vec()
                    };
                    out.push((k, shade(k, &offsets, &rays[span.clone()], &hits[span])));
                }
            }
            out
        })
        .collect();
    let count = values.len();
    for (k, c) in values {
        image.radiance[k] = c;
    }
    count
}

/// Pixels whose rays [`trace`] traces together.
const RUN: usize = 16;

/// The object each ray meets first (`NO_HIT` for none), the rays that
/// exist traced together; `None` for those that do not.
fn objects_met(engine: &dyn RayEngine, rays: &[Option<Ray>]) -> Vec<Option<u32>> {
    let some: Vec<Ray> = rays.iter().flatten().copied().collect();
    let mut hits = vec![None; some.len()];
    engine.intersect_batch(&some, &mut hits);
    let mut hits = hits.iter();
    rays.iter()
        .map(|r| {
            r.map(|_| {
                hits.next()
                    .expect("a hit a ray")
                    .map_or(NO_HIT, |h| h.object)
            })
        })
        .collect()
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
    let Some(near) = near_lights(&emissive, ids, w, h) else {
        return 0;
    };
    let around = Around {
        ids,
        near: &near,
        normal: &image.normal,
        radiance: &image.radiance,
        w: w as i64,
        h: h as i64,
    };
    let values: Vec<(usize, Vec3)> = near
        .window
        .clone()
        .into_par_iter()
        .filter(|&k| near.lit(k) && !near.on_light(k) && ids[k] != NO_HIT)
        .filter_map(|k| {
            let (sx, sy) = ((k % w) as f32 + 0.5, (k / w) as f32 + 0.5);
            let normal = image.normal[k];
            let j = around.best(ids[k], normal, sx, sy, |j| {
                !near.lit(j) && image.normal[j].dot(normal).abs() >= FACE_COS
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

/// Per pixel of the rows within [`WINDOW`] of the frame's lights (its
/// `window`), whether it shows a light, whether it is at or beside one
/// (grown by a pixel), and whether its 3 × 3 neighbourhood is free of
/// changes of surface ([`interior`]): [`Around`] reads no other rows, and
/// working them out for the whole frame took about as long as tracing the
/// lights' rims.
struct Near {
    window: Range<usize>,
    on_light: Vec<bool>,
    lit: Vec<bool>,
    interior: Vec<bool>,
}

impl Near {
    /// Pixel `j`'s entry of `mask`; false outside the window.
    fn at(&self, mask: &[bool], j: usize) -> bool {
        j.checked_sub(self.window.start)
            .and_then(|i| mask.get(i))
            .copied()
            .unwrap_or(false)
    }

    fn on_light(&self, j: usize) -> bool {
        self.at(&self.on_light, j)
    }

    fn lit(&self, j: usize) -> bool {
        self.at(&self.lit, j)
    }

    fn interior(&self, j: usize) -> bool {
        self.at(&self.interior, j)
    }
}

/// [`Near`] over the whole frame: silhouettes are everywhere.
fn whole_frame(emissive: &[bool], ids: &[u32], w: usize, h: usize) -> Near {
    let on_light: Vec<bool> = ids
        .par_iter()
        .map(|id| emissive.get(*id as usize).copied().unwrap_or(false))
        .collect();
    Near {
        window: 0..ids.len(),
        lit: dilate(&on_light, w, h),
        interior: interior(ids, w, h),
        on_light,
    }
}

/// The masks of the frame's pixels (`ids`, `w` × `h`) near the lights
/// that `emissive` marks; `None` where no pixel shows one.
fn near_lights(emissive: &[bool], ids: &[u32], w: usize, h: usize) -> Option<Near> {
    let emits = |id: &u32| emissive.get(*id as usize).copied().unwrap_or(false);
    let rows = || ids.par_chunks(w.max(1)).map(|r| r.iter().any(emits));
    let first = rows().position_first(|l| l)?;
    let last = rows().position_last(|l| l)?;
    let (a, b) = (first.saturating_sub(WINDOW), (last + 1 + WINDOW).min(h));
    let window = a * w..b * w;
    let on_light: Vec<bool> = ids[window.clone()].par_iter().map(emits).collect();
    Some(Near {
        lit: dilate(&on_light, w, b - a),
        interior: interior(&ids[window.clone()], w, b - a),
        on_light,
        window,
    })
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
    /// Whether a pixel is at or beside a light (its value may hold part
    /// of it), and whether its neighbours all show its surface.
    near: &'a Near,
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
        self.best(object, normal, sx, sy, |j| {
            !inside_only || self.near.interior(j)
        })
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
                let key = (other_face, self.near.lit(j), !self.near.interior(j), d);
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

/// `set` shifted by an offset of its own for pixel `k`, modulo the pixel
/// (a Cranley–Patterson rotation). With one set for every pixel a straight
/// rim at the same place in each of a row of pixels (a light's edge along
/// the frame's rows) was given the same share in all of them, off by up to
/// a point's spacing: a bias along the whole rim, which the eye and block
/// errors see. Shifted, each pixel's share is off by its own amount, and
/// the row averages them out.
fn shift(set: &[(f32, f32)], k: usize) -> Vec<(f32, f32)> {
    let mut rng = Pcg32::for_sample(SHIFT_SEED, k as u64, 0);
    let (u, v) = (rng.next_f32(), rng.next_f32());
    set.iter()
        .map(|&(x, y)| ((x + u).fract(), (y + v).fract()))
        .collect()
}

/// Seed of the pixels' shifts ([`shift`]): fixed, so that a frame is the
/// same whenever it is made.
const SHIFT_SEED: u64 = 0x5ca1_ab1e;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Camera, Projection};
    use crate::image::RangeMeta;

    /// A light's edge along a row of pixels, 4.6 sixty-fourths of the way
    /// down each: the rays' share below it, over the row, is the share the
    /// edge leaves (to three standard errors of a pixel's share, which is
    /// off by less than a point's spacing), where one set for every pixel
    /// gives every pixel 5 of 64 and the row 9% too much light.
    #[test]
    fn a_straight_rim_along_a_row_gets_its_share_over_the_row() {
        let full = hammersley(64);
        let edge = 4.6 / 64.0;
        let share = |set: &[(f32, f32)]| {
            set.iter().filter(|p| p.1 < edge).count() as f64 / set.len() as f64
        };
        let unshifted = share(&full);
        assert!((unshifted - edge as f64).abs() > 0.005, "{unshifted}");
        let n = 4096;
        let mean = (0..n).map(|k| share(&shift(&full, k))).sum::<f64>() / n as f64;
        let bound = 3.0 * (0.5 / 64.0) / (n as f64).sqrt();
        assert!(
            (mean - edge as f64).abs() < bound,
            "{mean} against {edge} (bound {bound})"
        );
    }

    #[test]
    fn masks_near_lights_are_those_of_the_whole_frame_where_they_are_read() {
        let (w, h) = (37, 41);
        let emissive: Vec<bool> = (0..10).map(|id| id == 9).collect();
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
            let near = near_lights(&emissive, &ids, w, h).expect("a light in view");
            let window = &near.window;
            assert!(window.start <= read.start && window.end >= read.end);
            let whole = (dilate(&on_light, w, h), self::interior(&ids, w, h));
            for (k, &on) in on_light.iter().enumerate() {
                let case = format!("edge after row {edge}, pixel {k}");
                assert_eq!(near.on_light(k), on, "{case}");
                assert_eq!(near.lit(k), whole.0[k], "{case}");
                if read.contains(&k) {
                    assert_eq!(near.interior(k), whole.1[k], "{case}");
                }
            }
        }
        // Without a light nothing is worked out.
        assert!(near_lights(&emissive, &vec![0; w * h], w, h).is_none());
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
