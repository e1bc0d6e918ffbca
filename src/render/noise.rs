//! Sampling to a noise target: each pixel's estimated error, and when a
//! pixel has had enough samples.
//!
//! A base image is seen by many frames, so its noise does not average away
//! from frame to frame: it reads as texture. Pixels therefore take samples
//! in rounds until the estimated relative standard error of their mean
//! luminance is below a target, or a sample limit is reached.
//!
//! **Estimator.** Each pixel keeps the count, mean and sum of squared
//! deviations of its samples' luminance (Welford's running variance,
//! batches merged by Chan's formula), so the standard error of its mean is
//! `√(m2 / (n − 1) / n)`. The alternative, the difference of the means of
//! the even and the odd samples, measures one degree of freedom per pixel;
//! the running variance measures `n − 1`, so over the 3 × 3 window below it
//! rests on about `9 (n − 1)` (63 at 8 samples: the variance to ±18 %, not
//! the ±47 % of nine half-splits), and single pixels whose few samples
//! happened to agree do not stop early. It ignores that the first
//! `⌊√spp⌋²` samples are stratified (over the pixel and over the light),
//! which makes their mean less noisy than independent samples: the
//! estimate errs high there, on the safe side.
//!
//! **Window and floor.** A pixel's error is the root mean square, over
//! its 3 × 3 window, of each pixel's relative standard error: the standard
//! error of its mean over the larger of its mean and a floor, [`FLOOR`]
//! times the median luminance of the pixels whose centre ray meets a
//! surface, after the first round. Relative error alone would sample a
//! black pixel forever; the median, unlike the mean, does not grow with the
//! few bright pixels of a light seen directly. Each pixel is made relative
//! to its own luminance before the window mixes them: a window's summed
//! variance over its summed luminance would let the bright, noisy edge of
//! a light hold the dark ceiling beside it at the sample limit, its own
//! samples all alike.
//!
//! **Bias.** Stopping a pixel when its estimate happens to be low favours
//! sample sets that missed rare bright paths; the window's many degrees of
//! freedom keep such luck small, and the minimum (`spp`) comes first.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::image::NO_HIT;

/// Where a pixel with luminance below the floor measures its error from,
/// as a share of the image's median luminance. Noise in pixels darker than
/// a tenth of the median is judged as if they were that bright: the target
/// then bounds their error in absolute terms, at a tenth of what it allows
/// a median pixel.
pub const FLOOR: f64 = 0.1;

/// Sample to a relative error per pixel instead of a flat count.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoiseTarget {
    /// Estimated relative standard error of a pixel's mean luminance at
    /// which it stops (0.01: 1 %).
    pub relative: f32,
    /// Most samples a pixel takes, at least the minimum
    /// (`RenderSettings::spp`).
    pub max_spp: u32,
}

/// Rec. 709 luminance, in the precision the estimates are kept in.
pub fn luminance(c: Vec3) -> f64 {
    0.2126 * c.x as f64 + 0.7152 * c.y as f64 + 0.0722 * c.z as f64
}

/// One pixel's luminance samples so far. Kept in `f32` (the image is) and
/// merged in `f64`: twelve bytes a pixel over a whole base image. The mean
/// is then known to 6e-8 of itself, which disturbs the variance only where
/// the samples spread by less than about a thousandth of it: far below
/// any noise a target asks for.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Moments {
    pub n: u32,
    pub mean: f32,
    /// Sum of squared deviations from the mean.
    pub m2: f32,
}

/// Welford's running moments of one batch of samples, in `f64`.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Batch {
    pub n: u32,
    pub mean: f64,
    pub m2: f64,
}

impl Batch {
    pub fn push(&mut self, y: f64) {
        self.n += 1;
        let d = y - self.mean;
        self.mean += d / self.n as f64;
        self.m2 += d * (y - self.mean);
    }
}

impl Moments {
    /// These moments and a batch's together (Chan et al.'s pairwise
    /// update: no cancellation between large sums).
    pub fn merge(self, b: &Batch) -> Moments {
        let n = self.n + b.n;
        if n == 0 {
            return self;
        }
        let (na, nb) = (self.n as f64, b.n as f64);
        let d = b.mean - self.mean as f64;
        let mean = self.mean as f64 + d * nb / n as f64;
        let m2 = self.m2 as f64 + b.m2 + d * d * na * nb / n as f64;
        Moments {
            n,
            mean: mean as f32,
            m2: m2 as f32,
        }
    }

    /// Estimated variance of the mean; infinite with fewer than two
    /// samples (nothing is known yet).
    fn variance_of_mean(&self) -> f64 {
        if self.n < 2 {
            return f64::INFINITY;
        }
        let n = self.n as f64;
        (self.m2 as f64).max(0.0) / (n - 1.0) / n
    }
}

/// The luminance below which a pixel's error is measured against the
/// floor: [`FLOOR`] times the median luminance of the pixels whose centre
/// ray meets a surface (or, where half of them are black, their mean).
pub(super) fn floor(moments: &[Moments], object_id: &[u32]) -> f64 {
    let mut seen: Vec<f32> = moments
        .iter()
        .zip(object_id)
        .filter(|(_, &id)| id != NO_HIT)
        .map(|(m, _)| m.mean)
        .collect();
    if seen.is_empty() {
        return 0.0;
    }
    let mid = seen.len() / 2;
    let median = *seen.select_nth_unstable_by(mid, f32::total_cmp).1 as f64;
    let level = if median > 0.0 {
        median
    } else {
        seen.iter().map(|&y| y as f64).sum::<f64>() / seen.len() as f64
    };
    FLOOR * level
}

/// Every pixel's estimated relative error (see the module's comment);
/// zero where its window is noiseless, infinite where a pixel of its
/// window has fewer than two samples.
pub(super) fn relative_errors(width: u32, moments: &[Moments], floor: f64) -> Vec<f32> {
    let w = width as usize;
    let h = moments.len() / w.max(1);
    let mut out = vec![0.0f32; moments.len()];
    use rayon::prelude::*;
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, e) in row.iter_mut().enumerate() {
            let (mut sum, mut k) = (0.0f64, 0u32);
            for yy in y.saturating_sub(1)..(y + 2).min(h) {
                for xx in x.saturating_sub(1)..(x + 2).min(w) {
                    let m = &moments[yy * w + xx];
                    let var = m.variance_of_mean();
                    if var > 0.0 {
                        sum += var / (m.mean as f64).max(floor).powi(2);
                    }
                    k += 1;
                }
            }
            *e = (sum / k as f64).sqrt() as f32;
        }
    });
    out
}

/// How many samples a pixel with `n` samples and estimated error `error`
/// should have after the next round; `None`: it is done. The variance of
/// a mean falls as `1/n`, so `n (error / target)²` would reach the target
/// if the estimate were exact. A round at most doubles the count, so that
/// an estimate that errs high (few samples, a noisy window) is checked
/// again before the limit is spent on it, and adds at least half: every
/// round passes over the whole image, and pixels just above the target
/// would otherwise creep up a sample a round.
pub(super) fn next_count(n: u32, error: f32, target: &NoiseTarget) -> Option<u32> {
    if n >= target.max_spp || error <= target.relative {
        return None;
    }
    let wanted = (n as f64 * (error as f64 / target.relative as f64).powi(2)).ceil();
    let next = wanted.clamp((1.5 * n as f64).ceil(), 2.0 * n as f64);
    Some((next as u32).min(target.max_spp))
}

/// What a base image's samples reached, over the pixels whose centre ray
/// meets a surface.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NoiseReport {
    /// The pixels the figures are over.
    pub pixels: u64,
    /// Mean samples per pixel.
    pub mean_spp: f64,
    /// Mean and 95th percentile of the estimated relative error; `None`
    /// where no pixel has two samples to estimate it from.
    pub error_mean: Option<f64>,
    pub error_p95: Option<f64>,
    /// Share of the pixels that stopped at the sample limit with their
    /// estimate still above the target; `None` without a target.
    pub at_limit: Option<f64>,
}

impl NoiseReport {
    pub(super) fn new(
        object_id: &[u32],
        samples: &[u32],
        errors: &[f32],
        target: Option<&NoiseTarget>,
    ) -> NoiseReport {
        let seen: Vec<usize> = (0..object_id.len())
            .filter(|&i| object_id[i] != NO_HIT)
            .collect();
        let pixels = seen.len() as u64;
        let share = |k: usize| k as f64 / pixels.max(1) as f64;
        let mut known: Vec<f32> = seen
            .iter()
            .map(|&i| errors[i])
            .filter(|e| e.is_finite())
            .collect();
        let (error_mean, error_p95) = if known.is_empty() {
            (None, None)
        } else {
            let mean = known.iter().map(|&e| e as f64).sum::<f64>() / known.len() as f64;
            // The nearest rank: the smallest error at least 95 % of the
            // pixels are at or below.
            let rank = ((0.95 * known.len() as f64).ceil() as usize).clamp(1, known.len()) - 1;
            let p95 = *known.select_nth_unstable_by(rank, f32::total_cmp).1 as f64;
            (Some(mean), Some(p95))
        };
        NoiseReport {
            pixels,
            mean_spp: seen.iter().map(|&i| samples[i] as f64).sum::<f64>() / pixels.max(1) as f64,
            error_mean,
            error_p95,
            at_limit: target.map(|t| {
                share(
                    seen.iter()
                        .filter(|&&i| samples[i] >= t.max_spp && errors[i] > t.relative)
                        .count(),
                )
            }),
        }
    }

    /// Several images' reports as one: means weighted by pixels, the
    /// 95th percentile the largest of the images' (an upper bound).
    pub fn combine(reports: &[NoiseReport]) -> Option<NoiseReport> {
        let pixels: u64 = reports.iter().map(|r| r.pixels).sum();
        if pixels == 0 {
            return None;
        }
        let weighted = |f: &dyn Fn(&NoiseReport) -> Option<f64>| -> Option<f64> {
            let mut sum = 0.0;
            for r in reports.iter().filter(|r| r.pixels > 0) {
                sum += f(r)? * r.pixels as f64;
            }
            Some(sum / pixels as f64)
        };
        Some(NoiseReport {
            pixels,
            mean_spp: weighted(&|r| Some(r.mean_spp))?,
            error_mean: weighted(&|r| r.error_mean),
            error_p95: reports
                .iter()
                .filter(|r| r.pixels > 0)
                .map(|r| r.error_p95)
                .try_fold(0.0f64, |m, e| e.map(|e| m.max(e))),
            at_limit: weighted(&|r| r.at_limit),
        })
    }
}

impl std::fmt::Display for NoiseReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let pct = |e: Option<f64>| e.map_or("unknown".into(), |e| format!("{:.2}%", 100.0 * e));
        write!(
            f,
            "relative error {} mean, {} at the 95th percentile; {:.1} samples per pixel",
            pct(self.error_mean),
            pct(self.error_p95),
            self.mean_spp
        )?;
        if let Some(s) = self.at_limit {
            write!(f, ", {:.2}% of pixels stopped at the limit", 100.0 * s)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merged_batches_give_the_moments_of_all_samples() {
        let ys: Vec<f64> = (0..37).map(|i| 10.0 + ((i * 7919) % 13) as f64).collect();
        let mut m = Moments::default();
        for chunk in ys.chunks(5) {
            let mut b = Batch::default();
            chunk.iter().for_each(|&y| b.push(y));
            m = m.merge(&b);
        }
        let n = ys.len() as f64;
        let mean = ys.iter().sum::<f64>() / n;
        let m2: f64 = ys.iter().map(|y| (y - mean).powi(2)).sum();
        assert_eq!(m.n, 37);
        assert!(
            (m.mean as f64 - mean).abs() <= mean * 1e-7,
            "{} {mean}",
            m.mean
        );
        assert!((m.m2 as f64 - m2).abs() <= m2 * 1e-5, "{} {m2}", m.m2);
    }

    #[test]
    fn counts_grow_at_most_twofold_up_to_the_limit() {
        let t = NoiseTarget {
            relative: 0.01,
            max_spp: 100,
        };
        assert_eq!(next_count(8, 0.01, &t), None);
        assert_eq!(next_count(8, 0.011, &t), Some(12)); // 8 · 1.21 = 9.7
        assert_eq!(next_count(8, 0.013, &t), Some(14)); // 8 · 1.69 = 13.5
        assert_eq!(next_count(8, 1.0, &t), Some(16));
        assert_eq!(next_count(64, 1.0, &t), Some(100));
        assert_eq!(next_count(100, 1.0, &t), None);
        assert_eq!(next_count(1, f32::INFINITY, &t), Some(2));
        assert_eq!(next_count(99, 0.011, &t), Some(100));
    }

    #[test]
    fn a_black_window_has_no_error_and_a_dark_one_is_measured_against_the_floor() {
        let m = |mean: f32, m2: f32| Moments { n: 4, mean, m2 };
        // 3 x 1: black, dark and noisy, bright and exact.
        let ms = [m(0.0, 0.0), m(0.1, 0.12), m(1.0, 0.0)];
        let e = relative_errors(3, &ms, 0.0);
        // The dark pixel's mean: variance 0.12 / 3 / 4 = 0.01, relative
        // variance 0.01 / 0.1² = 1, shared by the windows it is in.
        let close = |a: f32, b: f64| (a as f64 - b).abs() < 1e-6;
        assert!(close(e[0], (1.0f64 / 2.0).sqrt()), "{e:?}");
        assert!(close(e[1], (1.0f64 / 3.0).sqrt()), "{e:?}");
        assert!(close(e[2], (1.0f64 / 2.0).sqrt()), "{e:?}");
        // Below the floor, relative to the floor: 0.01 / 0.5² = 0.04.
        let floored = relative_errors(3, &ms, 0.5);
        assert!(close(floored[1], (0.04f64 / 3.0).sqrt()), "{floored:?}");
        let black = relative_errors(2, &[m(0.0, 0.0), m(0.0, 0.0)], 0.0);
        assert_eq!(black, vec![0.0, 0.0]);
    }
}
