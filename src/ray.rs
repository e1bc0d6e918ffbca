//! The ray, and where a ray leaving a surface starts: what cameras, the
//! scene's lights, both ray engines and every renderer share, so it lives
//! below all of them.

use glam::Vec3;

/// A ray segment `origin + t * dir` for `t` in `[tmin, tmax]`.
/// `dir` need not be normalized; `t` of a hit is in units of `dir`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
    pub tmin: f32,
    pub tmax: f32,
}

impl Ray {
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Self {
            origin,
            dir,
            tmin: 0.0,
            tmax: f32::INFINITY,
        }
    }

    pub fn segment(origin: Vec3, dir: Vec3, tmax: f32) -> Self {
        Self {
            origin,
            dir,
            tmin: 0.0,
            tmax,
        }
    }

    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// Moves a ray origin off the surface it lies on so that the new ray does not
/// hit that surface again, whatever the scene's scale.
///
/// The offset is relative to the magnitude of the point's coordinates (the
/// floating-point error of a computed hit point grows with them), pushed along
/// the geometric normal to the side `dir` leaves towards.
pub fn offset_origin(p: Vec3, normal: Vec3, dir: Vec3) -> Vec3 {
    // A few ulps of the largest coordinate, plus a tiny absolute floor for
    // points near the origin.
    const REL: f32 = 1.0 / 65536.0;
    const ABS: f32 = 1e-30;
    let mag = p.abs().max_element();
    let eps = mag * REL + ABS;
    let n = if normal.dot(dir) < 0.0 {
        -normal
    } else {
        normal
    };
    p + n * eps
}
