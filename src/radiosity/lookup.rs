//! Irradiance records looked up at shading points, with normal-aware
//! weights as Radiance interpolates its ambient cache.

use glam::Vec3;

use super::Simplified;

/// The records of one time, searchable per object in object space.
pub struct IrradianceCache {}

impl IrradianceCache {
    /// `indirect[i]` is the irradiance of `simplified.records[i]`.
    pub fn new(simplified: &Simplified, indirect: &[Vec3]) -> Self {
        let _ = (simplified, indirect);
        todo!("irradiance cache")
    }

    /// Indirect irradiance at object-space point `p` with unit normal `n` on
    /// `object`.
    pub fn irradiance(&self, object: u32, p: Vec3, n: Vec3) -> Vec3 {
        let _ = (object, p, n);
        todo!("irradiance lookup")
    }
}
