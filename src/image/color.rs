//! sRGB transfer functions and the preview tone map.

use std::sync::OnceLock;

use glam::Vec3;
use rayon::prelude::*;

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
///
/// Each value's byte is found among the 255 values where the encoding's
/// rounding steps up ([`steps`]), those of its bucket ([`Buckets`]): the
/// same byte as encoding it, without a power per channel, which made this
/// take about as long as a frame's synthesis in the viewer.
pub fn tonemap_srgb8(radiance: &[Vec3], exposure: f32) -> Vec<u8> {
    const CHUNK: usize = 4096;
    let scale = exposure.exp2();
    let table = Buckets::get();
    let mut out = vec![0; 3 * radiance.len()];
    out.par_chunks_mut(3 * CHUNK)
        .zip(radiance.par_chunks(CHUNK))
        .for_each(|(bytes, pixels)| {
            for (b, c) in bytes.chunks_exact_mut(3).zip(pixels) {
                let c = *c * scale;
                b.copy_from_slice(&[table.byte(c.x), table.byte(c.y), table.byte(c.z)]);
            }
        });
    out
}

/// The bytes of the values that share their sign, exponent and top seven
/// bits of mantissa (a bucket of at most 0.8% of its values' size), below
/// 1: the least and the greatest. Between them the value's byte is found
/// among those few [`steps`] (a rounding step of the encoding is at least
/// 0.9% of the value it lies at, so at most one): the same byte as
/// encoding the value, at a table lookup and a comparison. A search of all
/// 255 steps took 1.8 ms of every 512² frame in the viewer.
struct Buckets {
    steps: &'static [f32; 255],
    bytes: Vec<(u8, u8)>,
}

/// Bits of a value below its bucket's.
const BUCKET_SHIFT: u32 = 16;

impl Buckets {
    fn get() -> &'static Buckets {
        static BUCKETS: OnceLock<Buckets> = OnceLock::new();
        BUCKETS.get_or_init(|| {
            let steps = steps();
            let byte = |c: f32| steps.partition_point(|&s| s <= c) as u8;
            let bytes = (0..=1.0f32.to_bits() >> BUCKET_SHIFT)
                .map(|k| {
                    let lo = f32::from_bits(k << BUCKET_SHIFT);
                    let hi = f32::from_bits(((k + 1) << BUCKET_SHIFT) - 1);
                    (byte(lo), byte(hi))
                })
                .collect();
            Buckets { steps, bytes }
        })
    }

    /// The byte of value `c` (NaN black).
    #[inline]
    fn byte(&self, c: f32) -> u8 {
        // Also NaN and −0.
        if c.is_nan() || c <= 0.0 {
            return 0;
        }
        let Some(&(lo, hi)) = self.bytes.get((c.to_bits() >> BUCKET_SHIFT) as usize) else {
            return 255;
        };
        if lo == hi {
            return lo;
        }
        lo + self.steps[lo as usize..hi as usize].partition_point(|&s| s <= c) as u8
    }
}

/// A value's byte as the preview rounds its encoding (NaN black).
fn encoded_byte(x: f32) -> u8 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    (srgb_encode(x) * 255.0).round() as u8
}

/// For each byte `b` in `1..=255`, the least non-negative value whose
/// encoding rounds to `b` or more (found by bisection of the values' bit
/// patterns, which order non-negative floats).
fn steps() -> &'static [f32; 255] {
    static STEPS: OnceLock<[f32; 255]> = OnceLock::new();
    STEPS.get_or_init(|| {
        std::array::from_fn(|i| {
            let b = i as u8 + 1;
            let (mut lo, mut hi) = (0u32, 1.0f32.to_bits());
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if encoded_byte(f32::from_bits(mid)) >= b {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            f32::from_bits(lo)
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_preview_bytes_are_those_of_encoding_each_value() {
        let steps = steps();
        // Every value about each step, then values spread over the whole
        // range, below it, above it and not a number.
        let mut values: Vec<f32> = steps
            .iter()
            .flat_map(|s| {
                let b = s.to_bits() as i64;
                (b - 300..b + 300).map(|k| f32::from_bits(k.max(0) as u32))
            })
            .collect();
        values.extend((0..=1_000_000).map(|k| k as f32 / 1e6));
        values.extend((0..=1.0f32.to_bits()).step_by(61).map(f32::from_bits));
        values.extend([
            -1.0,
            -0.0,
            1.5,
            1e30,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ]);
        let radiance: Vec<Vec3> = values
            .chunks(3)
            .map(|c| {
                Vec3::from_slice(&[c[0], *c.get(1).unwrap_or(&0.0), *c.get(2).unwrap_or(&0.0)])
            })
            .collect();
        let bytes = tonemap_srgb8(&radiance, 0.0);
        for (c, b) in radiance.iter().flat_map(|c| c.to_array()).zip(&bytes) {
            assert_eq!(*b, encoded_byte(c), "value {c:e} ({:#x})", c.to_bits());
        }
        // Each step is where its byte begins.
        for (i, s) in steps.iter().enumerate() {
            assert_eq!(encoded_byte(*s), i as u8 + 1);
            assert_eq!(encoded_byte(f32::from_bits(s.to_bits() - 1)), i as u8);
        }
        // The exposure scales before the encoding.
        let c = [Vec3::new(0.1, 0.2, 0.4)];
        assert_eq!(tonemap_srgb8(&c, 1.0), tonemap_srgb8(&[c[0] * 2.0], 0.0));
    }

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
