//! How large base images must be: no base pixel coarser than a pixel of the
//! frames that will be synthesized from them, or the reprojection blurs and
//! blocks what a direct render would show (the paper's "resampled radiance"
//! error, its Table 3).

use anyhow::{bail, Result};

use crate::scene::Scene;

use super::BaseProjection;

/// The narrowest vertical field of view among the scene's cameras and walk
/// paths, in degrees (`None` when it has neither).
pub fn narrowest_fov(scene: &Scene) -> Option<f32> {
    scene
        .cameras
        .iter()
        .map(|c| c.vfov_deg)
        .chain(
            scene
                .paths
                .iter()
                .flat_map(|p| p.keys.iter().map(|k| k.vfov_deg)),
        )
        .filter(|v| v.is_finite() && *v > 0.0)
        .min_by(f32::total_cmp)
}

/// The side of square base images whose pixels subtend no larger an angle
/// than the centre pixel of a `frame` (W×H) pinhole view with vertical field
/// of view `vfov_deg`, rounded up to a multiple of 16.
///
/// A pinhole's centre pixel subtends `θ = 2 tan(vfov/2) / H` (its widest;
/// pixels off centre subtend less). An equal-area sphere of side `N` gives
/// every pixel the solid angle `4π / N²`, a square of side `√(4π) / N`; the
/// angular fisheye spreads 180° over its image circle's diameter, `π / N`
/// per pixel at its centre. So `N = ⌈√(4π) / θ⌉` or `⌈π / θ⌉`.
pub fn base_size(projection: BaseProjection, frame: (u32, u32), vfov_deg: f32) -> u32 {
    // Pixels are square, so the frame's width does not matter.
    let theta = 2.0 * (vfov_deg.to_radians() * 0.5).tan() / frame.1 as f32;
    let span = match projection {
        BaseProjection::Sphere => (4.0 * std::f32::consts::PI).sqrt(),
        BaseProjection::Fisheye => std::f32::consts::PI,
    };
    let n = (span / theta).ceil() as u32;
    n.div_ceil(16).max(1) * 16
}

/// The smallest side a base image may have. Below it a sphere pixel spans
/// more than 12.7° (4π/256 sr), so every surface but the nearest walls
/// falls into a pixel or two and frames show blocks, not the scene: such a
/// size is only ever a slip (`--size 7` for a 7-pixel frame?). The size
/// rule rounds up to a multiple of 16, so it never goes below this.
pub const MIN_SIDE: u32 = 16;

/// The largest side: base images are range images, which may hold at
/// most [`crate::image::MAX_PIXELS`] pixels to be read back.
pub fn max_side() -> u32 {
    (crate::image::MAX_PIXELS as f64).sqrt() as u32
}

/// The side of a bake's base images: `size` if given, else sized for
/// `frame`-sized frames at the scene's narrowest field of view; with the
/// sentence that says where it came from. `name` turns a field's name
/// (`size`, `frame_size`) into what the caller calls it (`--size`,
/// `options->size`).
pub fn resolve(
    scene: &Scene,
    size: Option<u32>,
    projection: BaseProjection,
    frame: (u32, u32),
    name: &dyn Fn(&str) -> String,
) -> Result<(u32, String)> {
    let kind = format!("{projection:?}").to_lowercase();
    let (size_name, frame_name) = (name("size"), name("frame_size"));
    match size {
        Some(n) if n < MIN_SIDE => bail!(
            "{size_name} {n} is below the smallest base image side, {MIN_SIDE}: a {kind} base of {n}x{n} pixels shows no scene; give {size_name} {MIN_SIDE} or more, or leave it out to size bases from {frame_name}"
        ),
        Some(n) if n > max_side() => bail!(
            "{size_name} {n} is above the largest base image side, {}: a base image may hold at most {} pixels",
            max_side(),
            crate::image::MAX_PIXELS
        ),
        Some(n) => Ok((n, format!("base images: {n}x{n} {kind} ({size_name})"))),
        None => {
            let (w, h) = frame;
            let Some(fov) = narrowest_fov(scene) else {
                bail!(
                    "{} has no camera or walk path to size base images from: give {size_name}",
                    scene.source.display()
                );
            };
            let n = base_size(projection, frame, fov);
            if n > max_side() {
                bail!(
                    "base images sized for {w}x{h} frames at the scene's narrowest field of view, {fov}°, would be {n}x{n} pixels, above the largest side, {}: lower {frame_name} or give {size_name}",
                    max_side()
                );
            }
            Ok((
                n,
                format!(
                    "base images: {n}x{n} {kind}, so that no base pixel is coarser than a pixel of a {w}x{h} frame at the scene's narrowest field of view, {fov}°"
                ),
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_39_degree_512_view_needs_a_sphere_of_about_2600() {
        let n = base_size(BaseProjection::Sphere, (512, 512), 39.3077);
        assert!((2500..2700).contains(&n), "{n}");
        assert_eq!(n % 16, 0);
        // The equal-area pixel is then no larger than the frame's centre pixel.
        let theta = 2.0 * (39.3077f32.to_radians() / 2.0).tan() / 512.0;
        let pixel = (4.0 * std::f32::consts::PI / (n as f32 * n as f32)).sqrt();
        assert!(pixel <= theta, "{pixel} > {theta}");
        // Twice the frame, twice the side (up to rounding to 16).
        let m = base_size(BaseProjection::Sphere, (1024, 1024), 39.3077);
        assert!((m as i64 - 2 * n as i64).abs() <= 16, "{m} vs {n}");
        // A fisheye covers half the directions over a wider circle.
        let f = base_size(BaseProjection::Fisheye, (512, 512), 39.3077);
        assert!(f < n && f > n / 2, "{f}");
        // The rule never goes below the smallest side, even for one pixel.
        assert_eq!(base_size(BaseProjection::Fisheye, (1, 1), 179.0), MIN_SIDE);
    }
}
