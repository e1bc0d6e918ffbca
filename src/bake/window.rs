//! Partial base images: the window of a base's projection that frames can
//! use. Seen from a view space outside it, a scene covers a few percent of
//! a base's sphere; the rest of the sphere's pixels see only sky, which a
//! frame gets by tracing its own ray to the sky (`synth::fill::sky`), so
//! baking, storing and reading them buys nothing.
//!
//! A base is kept in every direction in which a frame made anywhere in the
//! view space may see geometry, not only those in which the base itself
//! does: a frame's pixel that sees the sky takes it from every base that
//! holds that direction (the sky is at infinity, the same direction from
//! everywhere), so a base that dropped a direction another holds would
//! change the blend. Bases are only ever used at the times the plan
//! gives their views, and what they see then lies inside each object's
//! bounds posed at those times; seen from anywhere in the view space's
//! bounds `V`, a box `B` covers the directions the box `B − V` covers seen
//! from the origin. So every tile of [`TILE`]² pixels whose directions (a
//! cone around the tile's centre direction, wide enough for every pixel
//! corner of the tile plus two pixels) may meet such a box, or the sun's
//! disk, is kept, and the window is the rectangle around the kept tiles.
//! It is conservative (a box is larger than what it bounds) and holds at
//! least two pixels of sky round everything seen, so that splat
//! footprints and filters near silhouettes find the same neighbours as in
//! the whole image. Its corner is a multiple of [`ALIGN`] pixels and its
//! sides of [`STEP`] (or reach the image's edge), so that synthesis cuts
//! it into the same tiles and blocks as the whole image and, for frames in
//! the view space, makes the same frames bit for bit. Where the scene
//! surrounds the view space (an interior), the window is the whole image.

use anyhow::{ensure, Result};
use glam::{Affine3A, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::camera::Camera;
use crate::scene::{Light, Scene};

/// Multiple of the window's corner, in pixels: synthesis groups base
/// pixels into tiles of 16² and those into blocks of 8² tiles, in the order
/// it projects them; a window cornered on a block keeps that order.
pub const ALIGN: u32 = 128;

/// Multiple of the window's sides (where they do not reach the image's
/// edge): whole tiles of synthesis.
pub const STEP: u32 = 16;

/// Side of the squares of pixels tested against the scene's boxes.
const TILE: u32 = 16;

/// A rectangle of a base image's pixels, in the whole projection's pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct BaseWindow {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

impl BaseWindow {
    /// The whole `size` x `size` image.
    pub fn whole(size: u32) -> BaseWindow {
        BaseWindow {
            x: 0,
            y: 0,
            width: size,
            height: size,
        }
    }

    pub fn is_whole(&self, size: u32) -> bool {
        *self == BaseWindow::whole(size)
    }

    pub fn pixels(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// Checks that the window holds a pixel and lies inside a `size` x
    /// `size` image.
    pub fn check(&self, size: u32) -> Result<()> {
        let BaseWindow {
            x,
            y,
            width,
            height,
        } = *self;
        ensure!(
            width > 0 && height > 0,
            "{width}x{height} at ({x}, {y}) holds no pixel"
        );
        ensure!(
            u64::from(x) + u64::from(width) <= u64::from(size)
                && u64::from(y) + u64::from(height) <= u64::from(size),
            "{width}x{height} at ({x}, {y}) reaches outside the {size}x{size} base image"
        );
        Ok(())
    }

    /// `camera` (the whole projection) cropped to this window.
    pub fn crop(&self, camera: &Camera) -> Result<Camera> {
        camera.cropped(self.x, self.y, self.width, self.height)
    }
}

impl std::fmt::Display for BaseWindow {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}x{} at ({}, {})",
            self.width, self.height, self.x, self.y
        )
    }
}

/// What a base may see: boxes of geometry and directions of the sun.
struct Seen {
    boxes: Vec<(Vec3, Vec3)>,
    /// Unit direction towards the sun and its disk's angular radius.
    suns: Vec<(Vec3, f32)>,
}

impl Seen {
    /// Each object's bounds posed at each of `times` (once for an object
    /// that does not move), as seen from anywhere in `space` (the box of
    /// viewpoints): moved by every offset from a point of `space`, for a
    /// view from the origin. And the suns, whose disks show in the sky.
    fn of(scene: &Scene, times: &[f32], (vlo, vhi): (Vec3, Vec3)) -> Seen {
        let mut boxes = Vec::new();
        for o in &scene.objects {
            let Some((lo, hi)) = bounds(&o.mesh.positions) else {
                continue;
            };
            let poses: Vec<Affine3A> = if o.motion.is_static() {
                vec![o.motion.pose(times.first().copied().unwrap_or(0.0))]
            } else {
                times.iter().map(|&t| o.motion.pose(t)).collect()
            };
            for pose in poses {
                let corners = corners(lo, hi).map(|c| pose.transform_point3(c));
                boxes.extend(bounds(&corners).map(|(lo, hi)| (lo - vhi, hi - vlo)));
            }
        }
        let suns = scene
            .lights
            .iter()
            .filter_map(|l| match l {
                Light::Sun {
                    direction,
                    angular_diameter_deg,
                    ..
                } => Some((
                    direction.normalize_or_zero(),
                    0.5 * angular_diameter_deg.to_radians(),
                )),
                Light::Point { .. } => None,
            })
            .filter(|(d, _)| *d != Vec3::ZERO)
            .collect();
        Seen { boxes, suns }
    }

    /// Whether a direction within `half_angle` of unit `axis` may meet a
    /// box (from the origin) or a sun.
    fn cone_meets(&self, axis: Vec3, half_angle: f32) -> bool {
        self.suns
            .iter()
            .any(|&(d, r)| angle(axis, d) <= half_angle + r)
            || self
                .boxes
                .iter()
                .any(|&b| cone_meets_box(Vec3::ZERO, axis, half_angle, b))
    }
}

fn bounds(points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    let lo = points.iter().copied().reduce(Vec3::min)?;
    let hi = points.iter().copied().reduce(Vec3::max)?;
    (lo.is_finite() && hi.is_finite()).then_some((lo, hi))
}

fn corners(lo: Vec3, hi: Vec3) -> [Vec3; 8] {
    std::array::from_fn(|c| {
        Vec3::new(
            if c & 1 == 0 { lo.x } else { hi.x },
            if c & 2 == 0 { lo.y } else { hi.y },
            if c & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

/// The angle between two directions, accurate at every angle.
fn angle(a: Vec3, b: Vec3) -> f32 {
    a.cross(b).length().atan2(a.dot(b))
}

/// The least angle between unit `a` and the shorter great arc from unit
/// `u` to unit `v`.
fn angle_to_arc(a: Vec3, u: Vec3, v: Vec3) -> f32 {
    let ends = angle(a, u).min(angle(a, v));
    let Some(n) = u.cross(v).try_normalize() else {
        return ends;
    };
    let along = a.dot(n);
    let foot = a - along * n;
    if foot.length_squared() < 1e-12 {
        return ends;
    }
    if u.cross(foot).dot(n) >= 0.0 && foot.cross(v).dot(n) >= 0.0 {
        along.abs().atan2(foot.length()).min(ends)
    } else {
        ends
    }
}

/// Whether a direction from `p` within `half_angle` of unit `a` meets the
/// box `lo..hi`.
fn cone_meets_box(p: Vec3, a: Vec3, half_angle: f32, (lo, hi): (Vec3, Vec3)) -> bool {
    // The box lies in its bounding sphere, whose directions lie within
    // its angular radius of its centre's: most boxes are settled by that.
    let centre = 0.5 * (lo + hi);
    let to = centre - p;
    let (d, radius) = (to.length(), 0.5 * (hi - lo).length());
    if d > radius && angle(a, to) - (radius / d).asin() > half_angle {
        return false;
    }
    angle_to_box(p, a, lo, hi) <= half_angle
}

/// The least angle between unit direction `a` and a direction from `p` to
/// a point of the box `lo..hi`: zero where the ray from `p` along `a`
/// meets it (or `p` is inside), else the angle to the nearest edge of the
/// spherical polygon the box covers, which lies on an arc between two of
/// its corners' directions (the polygon is their convex hull, and every
/// such arc lies in it).
fn angle_to_box(p: Vec3, a: Vec3, lo: Vec3, hi: Vec3) -> f32 {
    // Slabs: the ray meets the box where its entering and leaving
    // parameters overlap at or after 0.
    let inv = a.recip();
    let (t0, t1) = ((lo - p) * inv, (hi - p) * inv);
    let (enter, leave) = (t0.min(t1), t0.max(t1));
    // NaN (0 · ∞ where the ray runs in a face's plane) decides nothing.
    let enter = [enter.x, enter.y, enter.z]
        .into_iter()
        .fold(0.0f32, |m, t| if t.is_nan() { m } else { m.max(t) });
    let leave = [leave.x, leave.y, leave.z]
        .into_iter()
        .fold(f32::INFINITY, |m, t| if t.is_nan() { m } else { m.min(t) });
    if enter <= leave {
        return 0.0;
    }
    let dirs: Vec<Vec3> = corners(lo, hi)
        .iter()
        .filter_map(|&c| (c - p).try_normalize())
        .collect();
    if dirs.len() < 8 {
        // `p` on a corner: every direction near the box is in reach.
        return 0.0;
    }
    let mut best = f32::INFINITY;
    for i in 0..8 {
        for j in i + 1..8 {
            best = best.min(angle_to_arc(a, dirs[i], dirs[j]));
        }
    }
    best
}

/// The box of viewpoints frames are made from: the scene's view space,
/// and the base views (which lie in it, or stand for it where the scene
/// has none).
pub fn viewpoints(scene: &Scene, views: &[Vec3]) -> (Vec3, Vec3) {
    let mut points = views.to_vec();
    if let Some((lo, hi)) = scene.view_space.map(|s| s.corners()) {
        points.extend([lo, hi]);
    }
    bounds(&points).unwrap_or((Vec3::ZERO, Vec3::ZERO))
}

/// The window of `camera`'s projection (the whole image's camera) that
/// holds every direction in which a viewpoint in `space` sees the scene at
/// `times` (the plan's, of every view), padded and aligned as the module
/// says. `camera` lies in `space`.
pub fn find(scene: &Scene, camera: &Camera, times: &[f32], space: (Vec3, Vec3)) -> BaseWindow {
    let (w, h) = camera.full_size();
    let seen = Seen::of(scene, times, space);
    let (tw, th) = (w.div_ceil(TILE), h.div_ceil(TILE));
    let kept: Vec<(u32, u32)> = (0..tw * th)
        .into_par_iter()
        .filter_map(|k| {
            let (tx, ty) = (k % tw, k / tw);
            let (x0, y0) = (tx * TILE, ty * TILE);
            let (x1, y1) = ((x0 + TILE).min(w), (y0 + TILE).min(h));
            let axis = camera
                .ray(0.5 * (x0 + x1) as f32, 0.5 * (y0 + y1) as f32)?
                .dir;
            // Every pixel corner of the tile, and the widest step between
            // neighbouring ones.
            let mut half_angle = 0.0f32;
            let mut step = 0.0f32;
            let mut any = false;
            let mut above: Vec<Option<Vec3>> = vec![None; (x1 - x0 + 1) as usize];
            for y in y0..=y1 {
                let mut left: Option<Vec3> = None;
                for (i, x) in (x0..=x1).enumerate() {
                    let d = camera.ray(x as f32, y as f32).map(|r| r.dir);
                    if let Some(d) = d {
                        any = true;
                        half_angle = half_angle.max(angle(axis, d));
                        for n in [left, above[i]].into_iter().flatten() {
                            step = step.max(angle(n, d));
                        }
                    }
                    left = d;
                    above[i] = d;
                }
            }
            if !any {
                return None;
            }
            // Two pixels of margin, and a little for rounding.
            let half_angle = half_angle + 2.0 * step + 1e-4;
            seen.cone_meets(axis, half_angle).then_some((x0, y0))
        })
        .collect();
    if kept.is_empty() {
        // Nothing to see from here: one tile, so that the image exists.
        return BaseWindow {
            x: 0,
            y: 0,
            width: STEP.min(w),
            height: STEP.min(h),
        };
    }
    let x0 = kept.iter().map(|k| k.0).min().unwrap_or(0);
    let y0 = kept.iter().map(|k| k.1).min().unwrap_or(0);
    let x1 = kept.iter().map(|k| k.0 + TILE).max().unwrap_or(w).min(w);
    let y1 = kept.iter().map(|k| k.1 + TILE).max().unwrap_or(h).min(h);
    let (x0, y0) = (x0 / ALIGN * ALIGN, y0 / ALIGN * ALIGN);
    let side = |a: u32, b: u32, n: u32| ((b - a).div_ceil(STEP) * STEP).min(n - a);
    BaseWindow {
        x: x0,
        y: y0,
        width: side(x0, x1, w),
        height: side(y0, y1, h),
    }
}

/// How much of the bake's base pixels its windows keep, and why the rest
/// is left out, for the bake's report.
pub fn describe(windows: &[BaseWindow], size: u32) -> String {
    let whole = u64::from(size) * u64::from(size) * windows.len() as u64;
    let kept: u64 = windows.iter().map(BaseWindow::pixels).sum();
    let partial = windows.iter().filter(|w| !w.is_whole(size)).count();
    if partial == 0 {
        return format!("base windows: every base keeps its whole {size}x{size} image");
    }
    format!(
        "base windows: the images of {partial} of {} views hold only the pixels that may see \
         the scene, {:.1}% of {size}x{size} each on average; left out: {:.1}% of the base \
         pixels, which see only sky (frames trace it)",
        windows.len(),
        100.0 * kept as f64 / whole as f64,
        100.0 * (whole - kept) as f64 / whole as f64
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_angle_to_a_box_is_zero_through_it_and_the_corner_angle_beside_it() {
        let (lo, hi) = (Vec3::new(-1.0, -1.0, 4.0), Vec3::new(1.0, 1.0, 6.0));
        assert_eq!(angle_to_box(Vec3::ZERO, Vec3::Z, lo, hi), 0.0);
        assert_eq!(
            angle_to_box(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z, lo, hi),
            0.0
        );
        // Looking along +x: the nearest point of the box is the edge x = 1,
        // y = 0, z = 4, at atan(4 / 1) from the axis.
        let got = angle_to_box(Vec3::ZERO, Vec3::X, lo, hi);
        let want = 4.0f32.atan2(1.0);
        assert!((got - want).abs() < 1e-5, "{got} vs {want}");
        // Looking away: the far corners, more than 90°.
        assert!(angle_to_box(Vec3::ZERO, -Vec3::Z, lo, hi) > 2.0);
    }

    #[test]
    fn the_angle_to_an_arc_is_measured_to_its_inside_or_its_ends() {
        let (u, v) = (Vec3::X, Vec3::Y);
        let a = Vec3::new(1.0, 1.0, 1.0).normalize();
        let got = angle_to_arc(a, u, v);
        let want = (1.0f32 / 3.0f32.sqrt()).asin();
        assert!((got - want).abs() < 1e-5, "{got} vs {want}");
        // Beyond the arc's end the end is nearest.
        let b = Vec3::new(1.0, -1.0, 0.0).normalize();
        assert!((angle_to_arc(b, u, v) - std::f32::consts::FRAC_PI_4).abs() < 1e-5);
    }

    #[test]
    fn windows_are_checked_against_the_image() {
        let w = BaseWindow {
            x: 128,
            y: 0,
            width: 64,
            height: 32,
        };
        w.check(256).unwrap();
        let e = w.check(160).unwrap_err().to_string();
        assert!(e.contains("outside the 160x160"), "{e}");
        let e = BaseWindow { width: 0, ..w }
            .check(256)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no pixel"), "{e}");
    }
}
