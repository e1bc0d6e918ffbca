//! Error of a rendered image against a reference, on luminance: per pixel,
//! as the paper measures it (§5: "luminance RMS / reference solution
//! average luminance"), and per 8×8 block, which keeps what a viewer sees
//! (seams, wrong shadows, patches of bias) and drops per-pixel noise.

use anyhow::{bail, ensure, Result};
use glam::Vec3;

use crate::camera::{Camera, Projection};
use crate::image::{RangeImage, RangeMeta};

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
    /// 8×8-block LRMS: the RMS over [`BLOCK`]×[`BLOCK`] blocks of
    /// `(mean Y_test − mean Y_ref over the block) / mean(Y_ref)`, each block
    /// weighted by its pixels. Zero-mean noise averages out within a block,
    /// structure does not; it never exceeds `lrms`.
    pub block_lrms: f64,
    /// The [`BLOCK_PERCENTILE`] percentile over blocks of
    /// `|mean Y_test − mean Y_ref over the block| / mean(Y_ref)`: a local
    /// artifact that the means hide, once it covers more than 1% of the
    /// blocks (of a 256² frame's 1,024 blocks, 11).
    pub block_p99: f64,
    /// Pixels the statistics were taken over.
    pub pixels: usize,
}

/// Side of the blocks of [`ImageError::block_lrms`] and
/// [`ImageError::block_p99`], in pixels: about the size of a detail a
/// viewer picks out of a frame, and much larger than a pixel's noise.
pub const BLOCK: u32 = 8;

/// The percentile of [`ImageError::block_p99`].
pub const BLOCK_PERCENTILE: usize = 99;

/// Row-major linear RGB and the size it has: images are compared only
/// where their widths and heights agree, not merely their pixel counts (a
/// 64×32 image against a 32×64 one has as many pixels, and its error
/// means nothing).
#[derive(Clone, Copy, Debug)]
pub struct Pixels<'a> {
    pub width: u32,
    pub height: u32,
    pub radiance: &'a [Vec3],
}

impl<'a> Pixels<'a> {
    pub fn new(width: u32, height: u32, radiance: &'a [Vec3]) -> Self {
        Self {
            width,
            height,
            radiance,
        }
    }

    /// `radiance` as `camera` saw it: its size is the camera's.
    pub fn of(camera: &Camera, radiance: &'a [Vec3]) -> Self {
        Self::new(camera.width, camera.height, radiance)
    }
}

impl<'a> From<&'a RangeImage> for Pixels<'a> {
    fn from(image: &'a RangeImage) -> Self {
        Self::new(image.width, image.height, &image.radiance)
    }
}

/// Compares `test` with `reference` over the pixels where `mask` is true,
/// or over all pixels without a mask.
///
/// Blocks tile the image from its top-left corner; where the width or
/// height is not a multiple of [`BLOCK`], the last column or row of blocks
/// is narrower and counts as the smaller blocks it is (by its pixels in
/// the RMS, as one block in the percentile). With a mask, a block is the
/// selected pixels in it, and a block with none is left out.
///
/// Errors, rather than a meaningless number, when the sizes differ (width
/// and height, not only the pixel count), an image holds other than its
/// size's pixels, a pixel is not finite, no pixel is selected or the
/// reference is black there.
pub fn compare<'a, 'b>(
    test: impl Into<Pixels<'a>>,
    reference: impl Into<Pixels<'b>>,
    mask: Option<&[bool]>,
) -> Result<ImageError> {
    let (t, r) = (test.into(), reference.into());
    ensure!(
        (t.width, t.height) == (r.width, r.height),
        "the image is {}x{} but the reference {}x{}: only images of one size compare pixel by pixel",
        t.width,
        t.height,
        r.width,
        r.height
    );
    for (what, p) in [("image", t), ("reference", r)] {
        ensure!(
            p.radiance.len() == p.width as usize * p.height as usize,
            "the {what} of {}x{} pixels holds {} values",
            p.width,
            p.height,
            p.radiance.len()
        );
    }
    let (test, reference) = (t.radiance, r.radiance);
    if let Some(m) = mask {
        ensure!(
            m.len() == reference.len(),
            "mask has {} entries for {} pixels",
            m.len(),
            reference.len()
        );
    }
    let (mut n, mut sum_ref, mut sum_test, mut sum_sq) = (0usize, 0.0f64, 0.0f64, 0.0f64);
    let blocks_across = t.width.div_ceil(BLOCK) as usize;
    let block_of = |i: usize| {
        let (x, y) = (i % t.width as usize, i / t.width as usize);
        (y / BLOCK as usize) * blocks_across + x / BLOCK as usize
    };
    // Per block: the sum of Y_test − Y_ref and the pixels selected.
    let mut blocks = vec![(0.0f64, 0usize); blocks_across * t.height.div_ceil(BLOCK) as usize];
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
        let b = &mut blocks[block_of(i)];
        b.0 += yt - yr;
        b.1 += 1;
    }
    ensure!(n > 0, "no pixel to compare (empty image or empty mask)");
    let mean_ref = sum_ref / n as f64;
    ensure!(
        mean_ref > 0.0,
        "the reference's mean luminance is {mean_ref}: a relative error needs a lit reference"
    );
    let (block_lrms, block_p99) = block_errors(&blocks, n, mean_ref);
    Ok(ImageError {
        lrms: (sum_sq / n as f64).sqrt() / mean_ref,
        bias: sum_test / sum_ref - 1.0,
        block_lrms,
        block_p99,
        pixels: n,
    })
}

/// The pixel-weighted RMS and the [`BLOCK_PERCENTILE`] percentile (the
/// nearest rank: the least value that at least that percentage of blocks
/// do not exceed) of the blocks' mean differences, relative to `mean_ref`,
/// from each block's summed difference and pixel count; `n` pixels in all.
fn block_errors(blocks: &[(f64, usize)], n: usize, mean_ref: f64) -> (f64, f64) {
    let mut sum_sq = 0.0;
    let mut means: Vec<f64> = Vec::with_capacity(blocks.len());
    for &(d, k) in blocks.iter().filter(|b| b.1 > 0) {
        let m = d / k as f64;
        sum_sq += k as f64 * m * m;
        means.push(m.abs());
    }
    means.sort_by(f64::total_cmp);
    let rank = (BLOCK_PERCENTILE * means.len()).div_ceil(100);
    let p99 = means[rank.clamp(1, means.len()) - 1];
    ((sum_sq / n as f64).sqrt() / mean_ref, p99 / mean_ref)
}

/// Refuses to compare images of different views: another projection (or
/// field of view) maps pixel `i` to another direction, and another camera
/// pose shows other surfaces there, so their pixel-by-pixel error measures
/// the difference of the views, not of the renderings. `scale` is a length
/// of the scene (its largest distance seen, say): camera positions within
/// 10⁻⁴ of it are one, as are directions within 10⁻⁴, so that the same
/// camera computed two ways (a path's pose, a named camera) still matches.
///
/// The scene time is not compared: a frame against a reference at another
/// time is how much the scene changed, which can be what is asked
/// ([`time_warning`] says it).
pub fn check_same_view(test: &RangeMeta, reference: &RangeMeta, scale: f32) -> Result<()> {
    let (a, b) = (&test.camera, &reference.camera);
    let projection = |p: &Projection| match p {
        Projection::Perspective { vfov_deg } => format!("a perspective ({vfov_deg}° vertical)"),
        Projection::Fisheye => "a fisheye".into(),
        Projection::Sphere => "a full-sphere".into(),
    };
    ensure!(
        a.projection == b.projection,
        "the image is {} view but the reference {}: their pixels look in other directions",
        projection(&a.projection),
        projection(&b.projection)
    );
    let scale = scale
        .max(a.position.length())
        .max(b.position.length())
        .max(f32::MIN_POSITIVE);
    let moved = a.position.distance(b.position) > 1e-4 * scale;
    let turned = [(a.forward, b.forward), (a.up, b.up)]
        .iter()
        .any(|(u, v)| u.distance(*v) > 1e-4);
    ensure!(
        !moved && !turned,
        "the image's camera is at {} looking along {} (up {}) but the reference's at {} along {} (up {}): \
         errors between different views measure the move, not the rendering; \
         make the image for the reference's camera",
        a.position,
        a.forward,
        a.up,
        b.position,
        b.forward,
        b.up
    );
    Ok(())
}

/// A warning when `test` and `reference` were made at different scene
/// times (see [`check_same_view`]).
pub fn time_warning(test: &RangeMeta, reference: &RangeMeta) -> Option<String> {
    (test.time != reference.time).then(|| {
        format!(
            "the image is at t = {} s but the reference at t = {} s: the error includes what moved between them",
            test.time, reference.time
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A one-row image of `v`.
    fn row(v: &[Vec3]) -> Pixels<'_> {
        Pixels::new(v.len() as u32, 1, v)
    }

    fn gradient(n: usize) -> Vec<Vec3> {
        (0..n)
            .map(|i| Vec3::new(0.1 + i as f32, 0.5 * i as f32 + 0.2, 2.0))
            .collect()
    }

    #[test]
    fn identical_images_have_no_error() {
        let a = gradient(64);
        let e = compare(row(&a), row(&a), None).unwrap();
        assert_eq!((e.lrms, e.bias, e.pixels), (0.0, 0.0, 64));
        assert_eq!((e.block_lrms, e.block_p99), (0.0, 0.0));
    }

    #[test]
    fn uniform_image_ten_percent_brighter() {
        let r = vec![Vec3::new(0.3, 0.6, 0.9); 100];
        let t: Vec<Vec3> = r.iter().map(|c| *c * 1.1).collect();
        let e = compare(row(&t), row(&r), None).unwrap();
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
        let e = compare(row(&t), row(&r), None).unwrap();
        assert!((e.lrms - 0.1 * rms / mean).abs() < 1e-6);
        assert!((e.bias - 0.1).abs() < 1e-6);
    }

    #[test]
    fn zero_mean_noise_has_error_but_no_bias() {
        let r = vec![Vec3::ONE; 4];
        let d = Vec3::splat(0.5);
        let t = vec![Vec3::ONE + d, Vec3::ONE - d, Vec3::ONE + d, Vec3::ONE - d];
        let e = compare(row(&t), row(&r), None).unwrap();
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
        let base = compare(row(&t), row(&r), None).unwrap();
        for k in [1e-6f32, 1e8] {
            let scale = |v: &[Vec3]| v.iter().map(|c| *c * k).collect::<Vec<_>>();
            let e = compare(row(&scale(&t)), row(&scale(&r)), None).unwrap();
            assert!((e.lrms - base.lrms).abs() < 1e-6 * base.lrms, "{k}: {e:?}");
            assert!((e.bias - base.bias).abs() < 1e-6 * base.bias, "{k}: {e:?}");
            assert!(
                (e.block_lrms - base.block_lrms).abs() < 1e-6 * base.block_lrms,
                "{k}: {e:?}"
            );
            assert!(
                (e.block_p99 - base.block_p99).abs() < 1e-6 * base.block_p99,
                "{k}: {e:?}"
            );
        }
    }

    #[test]
    fn mask_leaves_pixels_out() {
        let r = vec![Vec3::ONE; 4];
        let t = vec![Vec3::ONE, Vec3::ONE, Vec3::splat(100.0), Vec3::ONE];
        let mask = [true, true, false, true];
        let e = compare(row(&t), row(&r), Some(&mask)).unwrap();
        assert_eq!((e.lrms, e.bias, e.pixels), (0.0, 0.0, 3));
    }

    /// A uniform grey reference of `w x h` and a copy to alter.
    fn grey(w: u32, h: u32) -> (Vec<Vec3>, Vec<Vec3>) {
        let r = vec![Vec3::ONE; (w * h) as usize];
        (r.clone(), r)
    }

    #[test]
    fn per_pixel_noise_vanishes_in_blocks() {
        // A ±0.5 checkerboard on grey: LRMS 0.5, but every block holds as
        // many pixels above as below.
        let (r, mut t) = grey(32, 24);
        for (i, c) in t.iter_mut().enumerate() {
            let (x, y) = (i % 32, i / 32);
            *c += Vec3::splat(if (x + y) % 2 == 0 { 0.5 } else { -0.5 });
        }
        let e = compare(Pixels::new(32, 24, &t), Pixels::new(32, 24, &r), None).unwrap();
        assert!((e.lrms - 0.5).abs() < 1e-6, "{e:?}");
        assert!(e.block_lrms < 1e-9 && e.block_p99 < 1e-9, "{e:?}");
    }

    #[test]
    fn a_uniform_error_is_the_same_in_blocks() {
        let (r, t) = grey(24, 16);
        let t: Vec<Vec3> = t.iter().map(|c| *c * 1.25).collect();
        let e = compare(Pixels::new(24, 16, &t), Pixels::new(24, 16, &r), None).unwrap();
        for v in [e.lrms, e.block_lrms, e.block_p99] {
            assert!((v - 0.25).abs() < 1e-6, "{e:?}");
        }
    }

    /// A wrong patch of `blocks` whole blocks (error 1 against a reference
    /// of 1) in a 256² frame of 1,024 blocks.
    fn patch(blocks: usize) -> ImageError {
        let (r, mut t) = grey(256, 256);
        for b in 0..blocks {
            let (bx, by) = (b % 32, b / 32);
            for y in 0..8 {
                for x in 0..8 {
                    t[(by * 8 + y) * 256 + bx * 8 + x] = Vec3::splat(2.0);
                }
            }
        }
        compare(Pixels::new(256, 256, &t), Pixels::new(256, 256, &r), None).unwrap()
    }

    #[test]
    fn a_local_artifact_shows_in_the_block_percentile_alone() {
        // 16 of 1,024 blocks wrong by 1: a bias of 1/64 and an LRMS of
        // √(16/1024) = 1/8, but the 99th percentile is the patch's error.
        let e = patch(16);
        assert!((e.bias - 1.0 / 64.0).abs() < 1e-6, "{e:?}");
        assert!((e.lrms - 0.125).abs() < 1e-6, "{e:?}");
        assert!((e.block_lrms - 0.125).abs() < 1e-6, "{e:?}");
        assert!((e.block_p99 - 1.0).abs() < 1e-6, "{e:?}");
    }

    #[test]
    fn the_percentile_is_the_nearest_rank() {
        // Of 1,024 blocks the 1,014th smallest (⌈0.99 · 1024⌉) is the
        // 99th percentile: 10 wrong blocks lie above it, 11 reach it.
        assert_eq!(patch(10).block_p99, 0.0);
        assert!((patch(11).block_p99 - 1.0).abs() < 1e-6);
        // One block of one (a frame smaller than a block) is its own.
        let e = compare(row(&[Vec3::splat(3.0)]), row(&[Vec3::ONE]), None).unwrap();
        assert!((e.block_p99 - 2.0).abs() < 1e-6, "{e:?}");
    }

    #[test]
    fn partial_blocks_count_by_their_pixels() {
        // 10 x 3: a block of 8 x 3 pixels all 0.5 too bright and one of
        // 2 x 3 whose differences are +1, −1, +1, −1, +3, +3 (mean +1).
        let (r, mut t) = grey(10, 3);
        let right = [1.0, -1.0, 1.0, -1.0, 3.0, 3.0];
        for y in 0..3 {
            for x in 0..10 {
                let d = if x < 8 { 0.5 } else { right[y * 2 + x - 8] };
                t[y * 10 + x] += Vec3::splat(d);
            }
        }
        let e = compare(Pixels::new(10, 3, &t), Pixels::new(10, 3, &r), None).unwrap();
        // Blocks: √((24 · 0.25 + 6 · 1) / 30); pixels: √((6 + 22) / 30).
        assert!((e.block_lrms - 0.4f64.sqrt()).abs() < 1e-6, "{e:?}");
        assert!((e.lrms - (28.0f64 / 30.0).sqrt()).abs() < 1e-6, "{e:?}");
        // Two blocks: the larger error is the 99th percentile.
        assert!((e.block_p99 - 1.0).abs() < 1e-6, "{e:?}");
    }

    #[test]
    fn masked_pixels_leave_their_blocks() {
        // 16 x 8: the right block's pixels are all masked, except one.
        let (r, mut t) = grey(16, 8);
        for y in 0..8 {
            for x in 8..16 {
                t[y * 16 + x] = Vec3::splat(100.0);
            }
        }
        let mut mask: Vec<bool> = (0..128).map(|i| i % 16 < 8).collect();
        let e = compare(Pixels::new(16, 8, &t), Pixels::new(16, 8, &r), Some(&mask)).unwrap();
        assert_eq!((e.block_lrms, e.block_p99), (0.0, 0.0));
        // One pixel of it kept: a block of one pixel, 99 off.
        mask[8] = true;
        let e = compare(Pixels::new(16, 8, &t), Pixels::new(16, 8, &r), Some(&mask)).unwrap();
        assert!((e.block_p99 - 99.0).abs() < 1e-6, "{e:?}");
        assert!((e.block_lrms - 99.0 / 65f64.sqrt()).abs() < 1e-6, "{e:?}");
    }

    /// A block's mean difference is never farther from zero than the RMS
    /// of its pixels' (Jensen), so neither is the pixel-weighted RMS of
    /// the blocks' from the frame's.
    #[test]
    fn block_lrms_never_exceeds_lrms() {
        let mut rng = crate::rng::Pcg32::for_sample(7, 0, 0);
        for (w, h) in [(8, 8), (13, 9), (40, 17), (64, 64)] {
            let n = (w * h) as usize;
            let r: Vec<Vec3> = (0..n).map(|_| Vec3::splat(0.1 + rng.next_f32())).collect();
            let t: Vec<Vec3> = r
                .iter()
                .map(|c| *c * (0.5 + rng.next_f32()) + Vec3::splat(0.2 * rng.next_f32()))
                .collect();
            let e = compare(Pixels::new(w, h, &t), Pixels::new(w, h, &r), None).unwrap();
            assert!(e.block_lrms <= e.lrms * (1.0 + 1e-9), "{w}x{h}: {e:?}");
            assert!(e.block_lrms > 0.0 && e.block_p99 > 0.0, "{w}x{h}: {e:?}");
        }
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
        assert!(compare(row(&a), row(&a[..3]), None).is_err());
        assert!(compare(row(&a), row(&[Vec3::ZERO; 4]), None).is_err());
        assert!(compare(row(&a), row(&a), Some(&[false; 4])).is_err());
        assert!(compare(row(&a), row(&a), Some(&[true; 3])).is_err());
        let mut nan = a.clone();
        nan[2].y = f32::NAN;
        let msg = compare(row(&nan), row(&a), None).unwrap_err().to_string();
        assert!(msg.contains("pixel 2"), "{msg}");
        assert!(compare(row(&a), row(&nan), None).is_err());
    }

    /// A 64×32 image against a 32×64 one has as many pixels and no
    /// meaningful error: refused, naming both sizes.
    #[test]
    fn images_of_other_sizes_are_refused_even_with_as_many_pixels() {
        let a = gradient(64 * 32);
        let msg = compare(Pixels::new(64, 32, &a), Pixels::new(32, 64, &a), None)
            .unwrap_err()
            .to_string();
        assert!(msg.contains("64x32") && msg.contains("32x64"), "{msg}");
        assert!(compare(Pixels::new(64, 32, &a), Pixels::new(64, 32, &a), None).is_ok());
        // A size that does not hold the pixels given.
        let msg = compare(Pixels::new(8, 8, &a), Pixels::new(8, 8, &a), None)
            .unwrap_err()
            .to_string();
        assert!(msg.contains("8x8") && msg.contains("2048"), "{msg}");
    }

    fn meta(projection: Projection, position: glam::Vec3, target: glam::Vec3) -> RangeMeta {
        let camera = Camera::look_at(position, target, Vec3::Y, projection, 8, 8).unwrap();
        RangeMeta {
            camera,
            time: 0.5,
            scene: String::new(),
        }
    }

    #[test]
    fn images_of_other_views_are_refused() {
        let p = Projection::Perspective { vfov_deg: 40.0 };
        let (at, to) = (Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.0, 2.0, -5.0));
        let reference = meta(p, at, to);
        let same_view = |m: &RangeMeta| check_same_view(m, &reference, 10.0);
        assert!(same_view(&meta(p, at, to)).is_ok());
        // The same camera up to rounding.
        assert!(same_view(&meta(p, at + Vec3::splat(1e-6), to)).is_ok());
        for (other, needle) in [
            (meta(Projection::Fisheye, at, to), "a fisheye view"),
            (meta(Projection::Sphere, at, to), "a full-sphere view"),
            (
                meta(Projection::Perspective { vfov_deg: 60.0 }, at, to),
                "60° vertical",
            ),
            (meta(p, at + Vec3::X * 0.1, to), "the reference's at"),
            (meta(p, at, to + Vec3::X), "the reference's at"),
        ] {
            let msg = same_view(&other).unwrap_err().to_string();
            assert!(msg.contains(needle), "{msg}");
        }
        assert!(time_warning(&reference, &reference).is_none());
        let later = RangeMeta {
            time: 0.75,
            ..reference.clone()
        };
        let w = time_warning(&later, &reference).unwrap();
        assert!(w.contains("t = 0.75 s") && w.contains("t = 0.5 s"), "{w}");
    }
}
