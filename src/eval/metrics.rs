//! Pixel error of a rendered image against a reference, on luminance, as
//! the paper measures it (§5: "luminance RMS / reference solution average
//! luminance").

use anyhow::{bail, ensure, Result};
use glam::Vec3;

/// Rec. 709 luminance `Y` of linear RGB (the primaries the renderer uses).
pub fn luminance(c: Vec3) -> f64 {
    0.2126 * c.x as f64 + 0.7152 * c.y as f64 + 0.0722 * c.z as f64
}

/// How far a test image is from its reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageError {
    /// Relative luminance RMS: `RMS(Y_test - Y_ref) / mean(Y_ref)`. Noise
    /// and bias both raise it; 0 is a perfect match.
    pub lrms: f64,
    /// Relative bias `mean(Y_test) / mean(Y_ref) - 1`: what averaging many
    /// frames would not remove (a missing bounce shows here, noise does not).
    pub bias: f64,
    /// Pixels the statistics were taken over.
    pub pixels: usize,
}

/// Compares `test` with `reference` (row-major linear RGB of one size) over
/// the pixels where `mask` is true, or over all pixels without a mask.
///
/// Errors, rather than a meaningless number, when the sizes differ, a pixel
/// is not finite, no pixel is selected or the reference is black there.
pub fn compare(test: &[Vec3], reference: &[Vec3], mask: Option<&[bool]>) -> Result<ImageError> {
    ensure!(
        test.len() == reference.len(),
        "test image has {} pixels but the reference {}",
        test.len(),
        reference.len()
    );
    if let Some(m) = mask {
        ensure!(
            m.len() == reference.len(),
            "mask has {} entries for {} pixels",
            m.len(),
            reference.len()
        );
    }
    let (mut n, mut sum_ref, mut sum_test, mut sum_sq) = (0usize, 0.0f64, 0.0f64, 0.0f64);
    for (i, (&t, &r)) in test.iter().zip(reference).enumerate() {
        if mask.is_some_and(|m| !m[i]) {
            continue;
        }
        if !t.is_finite() {
            bail!("test pixel {i} is not finite: {t}");
        }
        if !r.is_finite() {
            bail!("reference pixel {i} is not finite: {r}");
        }
        let (yt, yr) = (luminance(t), luminance(r));
        n += 1;
        sum_ref += yr;
        sum_test += yt;
        sum_sq += (yt - yr) * (yt - yr);
    }
    ensure!(n > 0, "no pixel to compare (empty image or empty mask)");
    let mean_ref = sum_ref / n as f64;
    ensure!(
        mean_ref > 0.0,
        "the reference's mean luminance is {mean_ref}: a relative error needs a lit reference"
    );
    Ok(ImageError {
        lrms: (sum_sq / n as f64).sqrt() / mean_ref,
        bias: sum_test / sum_ref - 1.0,
        pixels: n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(n: usize) -> Vec<Vec3> {
        (0..n)
            .map(|i| Vec3::new(0.1 + i as f32, 0.5 * i as f32 + 0.2, 2.0))
            .collect()
    }

    #[test]
    fn identical_images_have_no_error() {
        let a = gradient(64);
        let e = compare(&a, &a, None).unwrap();
        assert_eq!((e.lrms, e.bias, e.pixels), (0.0, 0.0, 64));
    }

    #[test]
    fn uniform_image_ten_percent_brighter() {
        let r = vec![Vec3::new(0.3, 0.6, 0.9); 100];
        let t: Vec<Vec3> = r.iter().map(|c| *c * 1.1).collect();
        let e = compare(&t, &r, None).unwrap();
        assert!((e.lrms - 0.1).abs() < 1e-6, "lrms {}", e.lrms);
        assert!((e.bias - 0.1).abs() < 1e-6, "bias {}", e.bias);
    }

    #[test]
    fn scaled_gradient_matches_the_closed_form() {
        // Y_test = 1.1 Y_ref: LRMS = 0.1 sqrt(mean Y²) / mean Y.
        let r = gradient(50);
        let t: Vec<Vec3> = r.iter().map(|c| *c * 1.1).collect();
        let y: Vec<f64> = r.iter().map(|&c| luminance(c)).collect();
        let mean = y.iter().sum::<f64>() / y.len() as f64;
        let rms = (y.iter().map(|v| v * v).sum::<f64>() / y.len() as f64).sqrt();
        let e = compare(&t, &r, None).unwrap();
        assert!((e.lrms - 0.1 * rms / mean).abs() < 1e-6);
        assert!((e.bias - 0.1).abs() < 1e-6);
    }

    #[test]
    fn zero_mean_noise_has_error_but_no_bias() {
        let r = vec![Vec3::ONE; 4];
        let d = Vec3::splat(0.5);
        let t = vec![Vec3::ONE + d, Vec3::ONE - d, Vec3::ONE + d, Vec3::ONE - d];
        let e = compare(&t, &r, None).unwrap();
        assert!((e.lrms - 0.5).abs() < 1e-6);
        assert!(e.bias.abs() < 1e-12);
    }

    #[test]
    fn errors_do_not_depend_on_the_light_level() {
        let r = gradient(40);
        let t: Vec<Vec3> = r
            .iter()
            .enumerate()
            .map(|(i, c)| *c * (1.0 + 0.03 * (i % 5) as f32))
            .collect();
        let base = compare(&t, &r, None).unwrap();
        for k in [1e-6f32, 1e8] {
            let scale = |v: &[Vec3]| v.iter().map(|c| *c * k).collect::<Vec<_>>();
            let e = compare(&scale(&t), &scale(&r), None).unwrap();
            assert!((e.lrms - base.lrms).abs() < 1e-6 * base.lrms, "{k}: {e:?}");
            assert!((e.bias - base.bias).abs() < 1e-6 * base.bias, "{k}: {e:?}");
        }
    }

    #[test]
    fn mask_leaves_pixels_out() {
        let r = vec![Vec3::ONE; 4];
        let t = vec![Vec3::ONE, Vec3::ONE, Vec3::splat(100.0), Vec3::ONE];
        let mask = [true, true, false, true];
        let e = compare(&t, &r, Some(&mask)).unwrap();
        assert_eq!((e.lrms, e.bias, e.pixels), (0.0, 0.0, 3));
    }

    #[test]
    fn luminance_weights_sum_to_one() {
        assert!((luminance(Vec3::ONE) - 1.0).abs() < 1e-12);
        assert!(luminance(Vec3::Y) > luminance(Vec3::X));
        assert!(luminance(Vec3::X) > luminance(Vec3::Z));
    }

    #[test]
    fn meaningless_comparisons_are_errors() {
        let a = vec![Vec3::ONE; 4];
        assert!(compare(&a, &a[..3], None).is_err());
        assert!(compare(&a, &[Vec3::ZERO; 4], None).is_err());
        assert!(compare(&a, &a, Some(&[false; 4])).is_err());
        assert!(compare(&a, &a, Some(&[true; 3])).is_err());
        let mut nan = a.clone();
        nan[2].y = f32::NAN;
        let msg = compare(&nan, &a, None).unwrap_err().to_string();
        assert!(msg.contains("pixel 2"), "{msg}");
        assert!(compare(&a, &nan, None).is_err());
    }
}
