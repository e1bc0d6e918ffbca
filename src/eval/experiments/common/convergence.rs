//! The path tracer's convergence on one frame, against which every
//! experiment weighs the framework: measured at doubling sample counts,
//! read off at an error, and what a bake saves against it.

use anyhow::{Context, Result};
use glam::Vec3;
use serde::Serialize;

use super::plot::Series;
use super::table::{sig, Table};
use crate::accel::InstancedEngine;
use crate::camera::Camera;
use crate::eval::flip::Flip;
use crate::eval::metrics::{self, ImageError, Pixels};
use crate::eval::reference;
use crate::scene::Scene;

/// Seed of the renders compared with references (see
/// [`reference::REFERENCE_SEED`]).
pub const TEST_SEED: u64 = 1;

/// The path tracer's error at one sample count, on the preview frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConvergencePoint {
    pub spp: u32,
    pub seconds: f64,
    pub error: ImageError,
    /// Mean HDR-FLIP; `None` when FLIP is left out.
    pub flip: Option<f64>,
}

/// Where the path tracer's convergence curve may stop: at `max_spp`, or
/// past the largest cost per frame and below the smallest error of the
/// qualities measured, in LRMS and in FLIP, so that the plot shows where
/// (and whether) it crosses them and their sample counts at equal error
/// are read off measured points.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Target {
    pub max_spp: u32,
    pub seconds: f64,
    pub lrms: f64,
    /// `None` when FLIP is left out.
    pub flip: Option<f64>,
}

impl Target {
    /// Whether the curve ends at `point`.
    fn reached(&self, point: &ConvergencePoint) -> bool {
        let below_flip = match (point.flip, self.flip) {
            (Some(f), Some(target)) => f < target,
            _ => true,
        };
        point.spp >= self.max_spp
            || (point.seconds > 2.0 * self.seconds && point.error.lrms < self.lrms && below_flip)
    }
}

/// The path tracer's error on one frame at 1, 2, 4, ... samples per pixel,
/// until it reaches `target`'s sample count or has passed it in time
/// (twice over) and in error; FLIP of every point unless `flip` is `None`.
pub(crate) fn convergence(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    camera: &Camera,
    t: f32,
    reference: &[Vec3],
    target: Target,
    flip: Option<&Flip>,
) -> Result<Vec<ConvergencePoint>> {
    let mut points = Vec::new();
    let mut spp = 1;
    loop {
        let (radiance, seconds) = reference::path_trace(scene, engine, camera, t, spp, TEST_SEED)?;
        let error = metrics::compare(
            Pixels::of(camera, &radiance),
            Pixels::of(camera, reference),
            None,
        )
        .with_context(|| format!("path tracer convergence at {spp} spp"))?;
        let flip = flip
            .map(|f| f.hdr_mean(camera.width, camera.height, reference, &radiance))
            .transpose()
            .with_context(|| format!("FLIP of the path tracer at {spp} spp"))?;
        eprintln!(
            "path tracer convergence: {spp} spp: LRMS {:.4}{} ({seconds:.3} s)",
            error.lrms,
            flip.map_or(String::new(), |f| format!(", FLIP {f:.4}"))
        );
        let point = ConvergencePoint {
            spp,
            seconds,
            error,
            flip,
        };
        points.push(point);
        if target.reached(&point) {
            return Ok(points);
        }
        spp = (spp * 2).min(target.max_spp);
    }
}

/// The path tracer's cost of one sample per pixel of a frame, from the
/// largest measured render (small ones are dominated by fixed costs).
pub(crate) fn seconds_per_sample(curve: &[ConvergencePoint]) -> Option<f64> {
    let last = curve.iter().max_by_key(|p| p.spp)?;
    Some(last.seconds / last.spp as f64)
}

/// How the path tracer's sample count for an error was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Reach {
    /// Between two measured points of the convergence curve.
    Measured,
    /// The error is above the path tracer's at one sample per pixel: one
    /// sample (the least a frame can have) is counted.
    OneSample,
    /// Below the curve's last point: extended as LRMS ∝ 1/√spp, which
    /// ignores the reference's own noise and so understates the samples;
    /// FLIP, which follows no such law, along the slope of the curve's
    /// last two points on log-log axes.
    Extrapolated,
}

/// The error at which the path tracer is matched: users judge frames by
/// looking, and a frame can match the path tracer's LRMS long before it
/// looks as good (or the other way round).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Measure {
    Lrms,
    /// Mean HDR-FLIP.
    Flip,
}

impl Measure {
    /// The curve point's error in this measure, where it was measured.
    pub fn of(self, p: &ConvergencePoint) -> Option<f64> {
        match self {
            Measure::Lrms => Some(p.error.lrms),
            Measure::Flip => p.flip,
        }
    }
}

/// Samples per pixel at which the path tracer's error in `measure` falls
/// to `target`, read off its convergence curve: between the first
/// measured point at or below `target` and the one before it, interpolated
/// on log-log axes (where Monte Carlo error is a straight line). `None`
/// without points or where the curve cannot be extended (see
/// [`Reach::Extrapolated`]).
pub fn equal_error_spp(
    curve: &[ConvergencePoint],
    measure: Measure,
    target: f64,
) -> Option<(f64, Reach)> {
    let mut points: Vec<(f64, f64)> = curve
        .iter()
        .filter_map(|p| Some((p.spp as f64, measure.of(p)?)))
        .filter(|&(spp, e)| spp > 0.0 && e.is_finite() && e > 0.0)
        .collect();
    points.sort_by(|a, b| a.0.total_cmp(&b.0));
    let &(first_spp, first_e) = points.first()?;
    if !(target.is_finite() && target > 0.0) {
        return None;
    }
    if target >= first_e {
        return Some((first_spp, Reach::OneSample));
    }
    let along = |(sa, ea): (f64, f64), (sb, eb): (f64, f64)| {
        let (sa, sb, ea, eb) = (sa.ln(), sb.ln(), ea.ln(), eb.ln());
        (sa + (target.ln() - ea) * (sb - sa) / (eb - ea)).exp()
    };
    for w in points.windows(2) {
        if w[1].1 <= target {
            return Some((along(w[0], w[1]), Reach::Measured));
        }
    }
    let &(last_spp, last_e) = points.last()?;
    let spp = match measure {
        Measure::Lrms => last_spp * (last_e / target).powi(2),
        Measure::Flip => {
            let (a, b) = (
                points[points.len().checked_sub(2)?],
                points[points.len() - 1],
            );
            if b.1 >= a.1 {
                return None;
            }
            along(a, b)
        }
    };
    Some((spp, Reach::Extrapolated))
}

/// The path tracer's time per frame at the error `target` in `measure`
/// (its cost per sample times [`equal_error_spp`]), with the samples and
/// how they were found.
pub fn equal_error_seconds(
    curve: &[ConvergencePoint],
    measure: Measure,
    target: f64,
) -> Option<(f64, f64, Reach)> {
    let (spp, reach) = equal_error_spp(curve, measure, target)?;
    Some((spp * seconds_per_sample(curve)?, spp, reach))
}

/// The fewest frames for which baking once and synthesizing every frame
/// costs no more than path tracing each: `bake + n·synth ≤ n·path`, so
/// `n = ⌈bake / (path − synth)⌉`; `None` when a synthesized frame costs as
/// much as a path-traced one (never).
pub fn break_even(bake_s: f64, synth_s: f64, path_s: f64) -> Option<u64> {
    if path_s.partial_cmp(&synth_s) != Some(std::cmp::Ordering::Greater) || !bake_s.is_finite() {
        return None;
    }
    Some((bake_s.max(0.0) / (path_s - synth_s)).ceil().max(1.0) as u64)
}

/// How many times faster than path tracing the framework is over `n`
/// frames, its bake included: `n·path / (bake + n·synth)`.
pub fn speedup(n: u64, bake_s: f64, synth_s: f64, path_s: f64) -> f64 {
    let n = n as f64;
    n * path_s / (bake_s + n * synth_s)
}

/// The path tracer's convergence curve: samples per pixel, seconds, LRMS,
/// bias, block LRMS, block p99 and FLIP (empty where left out).
pub fn convergence_table(curve: &[ConvergencePoint]) -> Result<Table> {
    let mut t = Table::new([
        "spp",
        "seconds",
        "lrms",
        "bias",
        "block_lrms",
        "block_p99",
        "flip",
    ]);
    for p in curve {
        t.push([
            p.spp.to_string(),
            sig(p.seconds, 4),
            sig(p.error.lrms, 4),
            format!("{:+.5}", p.error.bias),
            sig(p.error.block_lrms, 4),
            sig(p.error.block_p99, 4),
            p.flip.map_or(String::new(), |f| sig(f, 4)),
        ])?;
    }
    Ok(t)
}

/// The path tracer's convergence curve as a plot series: its error in
/// `measure` against seconds per frame, where measured.
pub fn convergence_series(curve: &[ConvergencePoint], measure: Measure) -> Series {
    Series {
        label: format!("path tracer, 1..{} spp", curve.last().map_or(0, |p| p.spp)),
        points: curve
            .iter()
            .filter_map(|p| Some((p.seconds, measure.of(p)?)))
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(spp: u32, lrms: f64) -> ConvergencePoint {
        ConvergencePoint {
            spp,
            seconds: 0.01 * spp as f64,
            error: ImageError {
                lrms,
                bias: 0.0,
                block_lrms: lrms,
                block_p99: lrms,
                pixels: 1,
            },
            flip: None,
        }
    }

    /// A point whose FLIP is `flip` and whose LRMS is 1/√spp.
    fn flip_point(spp: u32, flip: f64) -> ConvergencePoint {
        ConvergencePoint {
            flip: Some(flip),
            ..point(spp, 1.0 / (spp as f64).sqrt())
        }
    }

    #[test]
    fn equal_error_is_interpolated_on_log_log_axes() {
        // Error 1/√spp: 0.25 lies at 16 spp exactly, between 8 and 32.
        let curve: Vec<_> = [1, 2, 8, 32]
            .map(|s| point(s, 1.0 / (s as f64).sqrt()))
            .to_vec();
        let (spp, reach) = equal_error_spp(&curve, Measure::Lrms, 0.25).unwrap();
        assert!((spp - 16.0).abs() < 1e-9, "{spp}");
        assert_eq!(reach, Reach::Measured);
        // A measured point is hit exactly.
        let (spp, _) = equal_error_spp(&curve, Measure::Lrms, 0.5).unwrap();
        assert!((spp - 4.0).abs() < 1e-9, "{spp}");
        // Worse than one sample: one sample.
        assert_eq!(
            equal_error_spp(&curve, Measure::Lrms, 3.0),
            Some((1.0, Reach::OneSample))
        );
        // Below the curve: 1/√spp carried on from the last point.
        let (spp, reach) = equal_error_spp(&curve, Measure::Lrms, 1.0 / 128.0).unwrap();
        assert!((spp - 16384.0).abs() < 1e-6, "{spp}");
        assert_eq!(reach, Reach::Extrapolated);
        // The time is the samples at the largest render's cost per sample.
        let (s, spp, _) = equal_error_seconds(&curve, Measure::Lrms, 0.25).unwrap();
        assert!((s - 0.16).abs() < 1e-9 && (spp - 16.0).abs() < 1e-9);
        assert_eq!(equal_error_spp(&[], Measure::Lrms, 0.1), None);
        assert_eq!(equal_error_spp(&curve, Measure::Lrms, f64::NAN), None);
    }

    #[test]
    fn equal_error_takes_the_first_crossing_of_a_noisy_curve() {
        // 4 spp dips below 0.3, 8 spp rises above it again: the path tracer
        // first reaches 0.3 between 2 and 4 spp.
        let curve = [point(1, 0.8), point(2, 0.5), point(4, 0.25), point(8, 0.35)];
        let (spp, reach) = equal_error_spp(&curve, Measure::Lrms, 0.3).unwrap();
        assert!(spp > 2.0 && spp < 4.0, "{spp}");
        assert_eq!(reach, Reach::Measured);
    }

    #[test]
    fn equal_flip_is_read_off_the_flip_curve() {
        // FLIP 0.4, 0.2, 0.1 at 1, 4, 16 spp (halving per 4x): 0.141 lies
        // at 8 spp on log-log axes, where LRMS would put 50 spp.
        let curve = [flip_point(1, 0.4), flip_point(4, 0.2), flip_point(16, 0.1)];
        let (spp, reach) = equal_error_spp(&curve, Measure::Flip, 0.2 / 2f64.sqrt()).unwrap();
        assert!((spp - 8.0).abs() < 1e-9, "{spp}");
        assert_eq!(reach, Reach::Measured);
        assert_eq!(
            equal_error_spp(&curve, Measure::Flip, 0.5),
            Some((1.0, Reach::OneSample))
        );
        // Below the curve: along its last slope, FLIP halving per 4x, so
        // 0.025 is two more factors of 4 past 16 spp.
        let (spp, reach) = equal_error_spp(&curve, Measure::Flip, 0.025).unwrap();
        assert!((spp - 256.0).abs() < 1e-6, "{spp}");
        assert_eq!(reach, Reach::Extrapolated);
        // A curve that has stopped falling cannot be extended.
        let flat = [flip_point(1, 0.4), flip_point(4, 0.2), flip_point(16, 0.2)];
        assert_eq!(equal_error_spp(&flat, Measure::Flip, 0.1), None);
        assert_eq!(equal_error_spp(&curve[..1], Measure::Flip, 0.1), None);
        // Without FLIP on the curve there is no equal FLIP.
        let lrms_only: Vec<_> = [1, 4, 16].map(|s| point(s, 0.5)).to_vec();
        assert_eq!(equal_error_spp(&lrms_only, Measure::Flip, 0.1), None);
        let (s, spp, _) = equal_error_seconds(&curve, Measure::Flip, 0.1).unwrap();
        assert!((s - 0.16).abs() < 1e-9 && (spp - 16.0).abs() < 1e-9);
    }

    #[test]
    fn break_even_and_speedup() {
        // Bake 100 s, 1 s a frame against 6 s: 20 frames to break even.
        // (100 + 20 = 120 = 20 x 6; at 19 frames 119 > 114.)
        assert_eq!(break_even(100.0, 1.0, 6.0), Some(20));
        // Not a whole number: the next frame.
        assert_eq!(break_even(100.0, 1.0, 4.0), Some(34));
        // Nothing to amortize: the first frame already pays.
        assert_eq!(break_even(0.0, 1.0, 2.0), Some(1));
        // Synthesis no cheaper than path tracing: never.
        assert_eq!(break_even(10.0, 2.0, 2.0), None);
        assert_eq!(break_even(10.0, 3.0, 2.0), None);
        assert_eq!(break_even(f64::NAN, 1.0, 2.0), None);
        // 300 frames: 1,800 s of path tracing against 100 + 300 s.
        assert!((speedup(300, 100.0, 1.0, 6.0) - 4.5).abs() < 1e-12);
        // At the break-even point the ratio reaches 1.
        assert!(speedup(20, 100.0, 1.0, 6.0) >= 1.0);
    }

    fn timed_point(spp: u32, seconds: f64) -> ConvergencePoint {
        ConvergencePoint {
            spp,
            seconds,
            error: ImageError {
                lrms: 1.0 / (spp as f64).sqrt(),
                bias: 0.0,
                block_lrms: 0.5 / (spp as f64).sqrt(),
                block_p99: 1.0 / (spp as f64).sqrt(),
                pixels: 1,
            },
            flip: None,
        }
    }

    #[test]
    fn the_curve_runs_until_it_passes_the_target_in_time_lrms_and_flip() {
        let target = Target {
            max_spp: 64,
            seconds: 0.5,
            lrms: 0.3,
            flip: Some(0.1),
        };
        // 16 spp: 1.6 s (past twice 0.5 s), LRMS 0.25 below 0.3.
        let mut p = timed_point(16, 1.6);
        p.flip = Some(0.2);
        assert!(!target.reached(&p), "FLIP 0.2 is above the target's 0.1");
        p.flip = Some(0.05);
        assert!(target.reached(&p));
        // Not yet past the time, or not below the LRMS.
        assert!(!target.reached(&timed_point(16, 0.9)));
        assert!(!target.reached(&timed_point(4, 1.6)));
        // Without FLIP, time and LRMS decide; the sample cap always ends it.
        let no_flip = Target {
            flip: None,
            ..target
        };
        assert!(no_flip.reached(&timed_point(16, 1.6)));
        assert!(target.reached(&timed_point(64, 0.01)));
    }
}
