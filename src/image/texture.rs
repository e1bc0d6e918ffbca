//! Textures as the image readers make them and materials sample them: the
//! readers' output type, so that reading an image needs nothing of scenes.

use std::path::PathBuf;

use glam::{Vec2, Vec3};

/// An RGB texture in linear values, addressed with wrapping `uv`.
#[derive(Clone, Debug)]
pub struct Texture {
    pub source: PathBuf,
    pub width: u32,
    pub height: u32,
    /// Row-major, top row first.
    pub texels: Vec<Vec3>,
}

impl Texture {
    /// The largest value of each channel: what bounds the reflectance the
    /// texture multiplies.
    pub fn largest_texel(&self) -> Vec3 {
        self.texels.iter().fold(Vec3::ZERO, |m, &t| m.max(t))
    }

    /// Bilinear lookup; `v = 0` is the bottom row, as in OBJ files.
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        let (w, h) = (self.width as usize, self.height as usize);
        let x = uv.x.rem_euclid(1.0) * w as f32 - 0.5;
        let y = (1.0 - uv.y.rem_euclid(1.0)) * h as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |i: f32, j: f32| {
            let i = (i as i64).rem_euclid(w as i64) as usize;
            let j = (j as i64).rem_euclid(h as i64) as usize;
            self.texels[j * w + i]
        };
        let top = at(x0, y0).lerp(at(x0 + 1.0, y0), fx);
        let bottom = at(x0, y0 + 1.0).lerp(at(x0 + 1.0, y0 + 1.0), fx);
        top.lerp(bottom, fy)
    }
}
