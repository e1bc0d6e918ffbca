//! The frame's camera as projection needs it, and the pixels a box of
//! points may reach in it.

use glam::{Affine3A, Vec2, Vec3};

use super::super::base::{Base, Bounds, Tile};
use super::SKY_Z;
use crate::camera::{Camera, Projection};

/// The frame's camera with what projecting into it needs precomputed.
pub struct Target {
    pub camera: Camera,
    /// Pixels per unit of `x/z` and `y/z` (pinhole frames).
    pub(super) focal: Option<f32>,
}

impl Target {
    pub fn new(camera: Camera) -> Self {
        let focal = match camera.projection {
            Projection::Perspective { vfov_deg } => {
                Some(0.5 * camera.height as f32 / (vfov_deg.to_radians() * 0.5).tan())
            }
            _ => None,
        };
        Self { camera, focal }
    }

    pub(super) fn local(&self, d: Vec3) -> Vec3 {
        let c = &self.camera;
        Vec3::new(d.dot(c.right), d.dot(c.up), d.dot(c.forward))
    }

    /// Pinhole pixel position of a camera-space vector, `None` behind.
    #[inline]
    pub(super) fn pinhole(&self, f: f32, d: Vec3) -> Option<Vec2> {
        let l = self.local(d);
        if l.z <= 0.0 {
            return None;
        }
        let inv = f / l.z;
        Some(Vec2::new(
            0.5 * self.camera.width as f32 + l.x * inv,
            0.5 * self.camera.height as f32 - l.y * inv,
        ))
    }

    /// Continuous pixel position of a world point (not clipped to the
    /// image, so that splats can cross its edge) and its distance.
    #[inline]
    pub fn point(&self, p: Vec3) -> Option<(Vec2, f32)> {
        let d = p - self.camera.position;
        match self.focal {
            Some(f) => self.pinhole(f, d),
            None => self.camera.project(p),
        }
        .map(|px| (px, d.length()))
    }

    /// About how many frame pixels a base pixel's side spans, seen at
    /// distance `z` from the frame's camera: the base pixel's angle times
    /// its distance from the base's camera, over `z`, over the angle of a
    /// frame pixel (each at its image's centre).
    pub(super) fn pixel_side(&self, base: &Base, point: Vec3, z: f32) -> f32 {
        let seen = pixel_angle(&base.camera) * point.distance(base.camera.position) / z;
        (seen / pixel_angle(&self.camera)).max(1e-3)
    }

    /// Pixel position of a direction (a point at infinity).
    #[inline]
    pub fn direction(&self, d: Vec3) -> Option<Vec2> {
        match self.focal {
            Some(f) => self.pinhole(f, d),
            None => {
                // Far enough that the position's rounding does not turn
                // the direction, near enough that its square stays finite.
                let far = 1e3 * (1.0 + self.camera.position.abs().max_element());
                self.camera.project(self.camera.position + d * far)
            }
        }
    }

    /// Rows a box of points may reach, or `None` where the frame cannot
    /// see it. Only pinhole frames are culled.
    pub(super) fn rows(&self, b: &Bounds, directions: bool) -> Option<(u32, u32)> {
        self.reach(b, directions).map(|r| r.rows)
    }

    /// The part of the frame a box of points may reach and how near it
    /// comes, or `None` where the frame cannot see it. Only pinhole frames
    /// are culled and bounded; other frames are reached whole.
    pub(super) fn reach(&self, b: &Bounds, directions: bool) -> Option<Reach> {
        let (w, h) = (self.camera.width, self.camera.height);
        let near = if directions {
            SKY_Z
        } else {
            let p = self.camera.position;
            (b.lo - p).max(p - b.hi).max(Vec3::ZERO).length()
        };
        let whole = Reach {
            rows: (0, h),
            cols: (0, w),
            near,
        };
        let Some(f) = self.focal else {
            return Some(whole);
        };
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        let mut behind = 0;
        // Corners outside each side of the frustum (with a pixel to spare):
        // a box with all eight outside one side is not seen.
        let (ax, ay) = ((0.5 * w as f32 + 2.0) / f, (0.5 * h as f32 + 2.0) / f);
        let mut outside = [0; 4];
        for c in b.corners() {
            let l = if directions {
                self.local(c)
            } else {
                self.local(c - self.camera.position)
            };
            outside[0] += (l.x > l.z * ax) as u32;
            outside[1] += (l.x < -l.z * ax) as u32;
            outside[2] += (l.y > l.z * ay) as u32;
            outside[3] += (l.y < -l.z * ay) as u32;
            if l.z <= 0.0 {
                behind += 1;
                continue;
            }
            let inv = f / l.z;
            let q = Vec2::new(l.x * inv, -l.y * inv);
            lo = lo.min(q);
            hi = hi.max(q);
        }
        if behind == 8 || outside.contains(&8) {
            return None;
        }
        if behind > 0 {
            return Some(whole);
        }
        let half = Vec2::new(w as f32, h as f32) * 0.5;
        let (lo, hi) = (lo + half - 1.0, hi + half + 1.0);
        if hi.x < 0.0 || hi.y < 0.0 || lo.x > w as f32 || lo.y > h as f32 {
            return None;
        }
        let span =
            |lo: f32, hi: f32, n: u32| (lo.max(0.0) as u32, (hi.ceil().max(0.0) as u32 + 1).min(n));
        Some(Reach {
            rows: span(lo.y, hi.y, h),
            cols: span(lo.x, hi.x, w),
            near,
        })
    }

    /// What a tile of a pass may reach (its points moved to the frame's
    /// time).
    pub(super) fn tile_reach(&self, tile: &Tile, moves: &[Option<Affine3A>]) -> Option<Reach> {
        let mut range: Option<Reach> = None;
        let mut add = |r: Option<Reach>| {
            if let Some(r) = r {
                range = Some(range.map_or(r, |u| u.union(&r)));
            }
        };
        if let Some(b) = &tile.fixed {
            add(self.reach(b, false));
        }
        if let Some(b) = &tile.sky {
            add(self.reach(b, true));
        }
        for (o, b) in &tile.moving {
            match moves.get(*o as usize).and_then(Option::as_ref) {
                Some(m) => {
                    let mut moved = Bounds::EMPTY;
                    for c in b.corners() {
                        moved.grow(m.transform_point3(c));
                    }
                    add(self.reach(&moved, false));
                }
                None => add(self.reach(b, false)),
            }
        }
        range
    }
}

/// The frame pixels a box of points may reach (half-open rows and
/// columns) and its nearest distance from the frame's camera.
#[derive(Clone, Copy, Debug)]
pub(super) struct Reach {
    pub(super) rows: (u32, u32),
    pub(super) cols: (u32, u32),
    pub(super) near: f32,
}

impl Reach {
    pub(super) fn union(&self, o: &Reach) -> Reach {
        Reach {
            rows: (self.rows.0.min(o.rows.0), self.rows.1.max(o.rows.1)),
            cols: (self.cols.0.min(o.cols.0), self.cols.1.max(o.cols.1)),
            near: self.near.min(o.near),
        }
    }
}

/// The angle a camera's centre pixel subtends (every pixel's, for the
/// equal-area sphere).
fn pixel_angle(c: &Camera) -> f32 {
    let (w, h) = c.full_size();
    match c.projection {
        Projection::Perspective { vfov_deg } => {
            2.0 * (vfov_deg.to_radians() * 0.5).tan() / h as f32
        }
        Projection::Fisheye => std::f32::consts::PI / w.min(h) as f32,
        Projection::Sphere => (4.0 * std::f32::consts::PI).sqrt() / h as f32,
    }
}
