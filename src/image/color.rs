//! sRGB transfer functions and the preview tone map.

use glam::Vec3;

/// Linear value in `[0, 1]` to its sRGB encoding (IEC 61966-2-1).
pub fn srgb_encode(x: f32) -> f32 {
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// sRGB-encoded value in `[0, 1]` to linear.
pub fn srgb_decode(x: f32) -> f32 {
    if x <= 0.040_45 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

/// 8-bit sRGB bytes (`RGBRGB...`) for a preview: radiance scaled by
/// `2^exposure` (exposure in photographic stops), clipped to `[0, 1]` per
/// channel, sRGB-encoded and rounded. Clipping rather than a global operator
/// keeps previews of different frames directly comparable; NaN shows black.
pub fn tonemap_srgb8(radiance: &[Vec3], exposure: f32) -> Vec<u8> {
    let scale = exposure.exp2();
    radiance
        .iter()
        .flat_map(|c| (*c * scale).to_array())
        .map(|x| {
            let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
            (srgb_encode(x) * 255.0).round() as u8
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_every_byte() {
        for b in 0..=255u8 {
            let x = b as f32 / 255.0;
            let back = srgb_encode(srgb_decode(x));
            assert!((back - x).abs() < 1e-5, "{b}: {x} -> {back}");
        }
    }

    #[test]
    fn srgb_known_points() {
        // The standard's mid-grey: linear 0.214 encodes to about 0.5.
        assert!((srgb_encode(0.214_041_14) - 0.5).abs() < 1e-5);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_decode(1.0) - 1.0).abs() < 1e-6);
        assert_eq!(srgb_decode(0.0), 0.0);
        // Both branches meet at the breakpoint.
        assert!((srgb_encode(0.003_130_8) - 0.040_45).abs() < 1e-5);
    }

    #[test]
    fn tonemap_clips_scales_and_blacks_out_nan() {
        let px = [
            Vec3::new(0.18, 2.0, -1.0),
            Vec3::new(f32::NAN, f32::INFINITY, 0.0),
        ];
        assert_eq!(tonemap_srgb8(&px, 0.0), vec![118, 255, 0, 0, 255, 0]);
        // One stop more light doubles the linear value before encoding.
        // sRGB(0.18) = 0.4614, i.e. byte 117.6.
        let half = [Vec3::splat(0.18 / 2.0)];
        assert_eq!(tonemap_srgb8(&half, 1.0), vec![118, 118, 118]);
    }
}
