//! The ray: the one geometric type that cameras, the scene's samplers, both
//! ray engines and every renderer share, so it lives below all of them.

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
