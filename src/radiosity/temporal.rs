//! Temporal decomposition of indirect illumination (paper §5.1.2).
//!
//! Indirect light changes slowly while objects move, so it is solved at a
//! few times only: at the two ends of the animation, then recursively at
//! the midpoint of every interval whose two end solutions disagree by more
//! than the quality allows. In between, each record's irradiance is
//! interpolated linearly; records live in object space, so an object's
//! records move with it and only their values are blended.
//!
//! How the quality `q` sets the tests (see `docs/multipass.md`):
//!
//! * relative RMS bound `b = 0.1 + 0.4 (1 - q)²`: an interval is split
//!   while `RMS_i(Y₁ - Y₀) / mean_i((Y₀ + Y₁) / 2) > b`, over the
//!   luminance `Y` of every record (0.296 at q = 0.3, 0.164 at 0.6, 0.104
//!   at 0.9). The floor of 0.1 lies above the solver's own noise: two
//!   solutions of the Cornell box 1/16 s apart differ by 6–7 % relative
//!   RMS from their shadow-ray sampling alone, so a lower bound would only
//!   split every interval to the depth limit;
//! * a record is *unchanged* when `|Y₁ - Y₀| ≤ b · mean`; the interval is
//!   also split while fewer than a fraction `q` of the records are
//!   unchanged (a broad change that stays just under the RMS bound);
//! * bisection stops at depth `1 + ⌊5 q⌋` (2 at q = 0.3, 5 at 0.9), i.e.
//!   at most `2^depth + 1` solves.

use std::time::Instant;

use anyhow::{ensure, Context, Result};
use glam::Vec3;

use super::{IndirectSolution, Quality, Simplified};
use crate::accel::{InstancedEngine, RayEngine};
use crate::progress::{ProgressBar, ProgressStyle};
use crate::scene::Scene;

/// Solutions at the times chosen by recursive bisection, in time order.
#[derive(Clone, Debug, PartialEq)]
pub struct TimeSeries {
    pub times: Vec<f32>,
    pub solutions: Vec<IndirectSolution>,
    /// The quality the decomposition was made for.
    pub quality: Quality,
    pub stats: DecomposeStats,
}

/// What the decomposition did and cost.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DecomposeStats {
    /// Radiosity solves, one per time of the list.
    pub solves: usize,
    /// Deepest bisection level reached (0: the two ends only, or a static
    /// scene).
    pub depth: u32,
    /// Bisection depth allowed by the quality.
    pub max_depth: u32,
    /// Whether the scene is static: one solution, no decomposition.
    pub static_scene: bool,
    /// Every interval tested, in the order tested.
    pub intervals: Vec<IntervalTest>,
    /// Wall time of the whole decomposition, solves included.
    pub seconds: f64,
}

/// The coherence test of one interval between two solutions.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IntervalTest {
    pub t0: f32,
    pub t1: f32,
    pub depth: u32,
    /// Pointwise luminance RMS over the mean of the two solutions.
    pub relative_rms: f64,
    /// Fraction of records whose luminance changed by at most the bound.
    pub unchanged: f64,
    pub split: bool,
}

/// The thresholds a quality sets (formulas in the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thresholds {
    pub relative_rms: f64,
    pub unchanged_fraction: f64,
    pub max_depth: u32,
}

impl Thresholds {
    pub fn for_quality(q: Quality) -> Self {
        let q = q.get() as f64;
        Self {
            relative_rms: 0.1 + 0.4 * (1.0 - q) * (1.0 - q),
            unchanged_fraction: q,
            max_depth: 1 + (5.0 * q).floor() as u32,
        }
    }
}

impl TimeSeries {
    /// Per-record indirect irradiance at `t`, linear between the bracketing
    /// solutions and held outside them.
    pub fn indirect_at(&self, t: f32) -> Vec<Vec3> {
        let (Some(first), Some(last)) = (self.solutions.first(), self.solutions.last()) else {
            return Vec::new();
        };
        if t.is_nan() || t <= self.times[0] {
            return first.indirect.clone();
        }
        if t >= self.times[self.times.len() - 1] {
            return last.indirect.clone();
        }
        let k = self.times.partition_point(|&s| s <= t) - 1;
        let (t0, t1) = (self.times[k], self.times[k + 1]);
        let w = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
        let (a, b) = (&self.solutions[k].indirect, &self.solutions[k + 1].indirect);
        a.iter().zip(b).map(|(&a, &b)| a + (b - a) * w).collect()
    }
}

/// Relative luminance RMS of `b - a` and the fraction of records whose
/// luminance changed by at most `bound` times the mean, over the records
/// lit in either solution: the unlit sides of surfaces (a wall's outside,
/// a box's inside) would otherwise dilute both.
pub fn compare(a: &[Vec3], b: &[Vec3], bound: f64) -> (f64, f64) {
    let y = |v: Vec3| 0.2126 * v.x as f64 + 0.7152 * v.y as f64 + 0.0722 * v.z as f64;
    let lit: Vec<(f64, f64)> = a
        .iter()
        .zip(b)
        .map(|(&a, &b)| (y(a), y(b)))
        .filter(|&(a, b)| a != 0.0 || b != 0.0)
        .collect();
    let n = lit.len();
    if n == 0 {
        return (0.0, 1.0);
    }
    let (mut sq, mut sum) = (0.0, 0.0);
    for &(a, b) in &lit {
        let d = b - a;
        sq += d * d;
        sum += 0.5 * (a + b);
    }
    let (rms, mean) = ((sq / n as f64).sqrt(), sum / n as f64);
    if rms == 0.0 {
        return (0.0, 1.0);
    }
    if mean.abs() <= 0.0 {
        return (f64::INFINITY, 0.0);
    }
    let tol = bound * mean.abs();
    let unchanged = lit.iter().filter(|(a, b)| (b - a).abs() <= tol).count();
    (rms / mean.abs(), unchanged as f64 / n as f64)
}

/// Solves at the ends of the animation and bisects while the two ends of an
/// interval disagree by more than `quality` allows. A static scene gets one
/// solution.
pub fn decompose(
    scene: &Scene,
    simplified: &Simplified,
    engine: &mut dyn InstancedEngine,
    quality: Quality,
) -> Result<TimeSeries> {
    let mut engines = super::solver::Engines::default();
    decompose_with(scene, simplified, engine, quality, |sc, s, e, t, q| {
        super::solver::solve_posing(sc, s, e, t, q, &mut engines)
    })
}

/// [`decompose`] with the solver given, so that the decomposition can be
/// driven by any source of solutions (tests use synthetic ones).
pub fn decompose_with<F>(
    scene: &Scene,
    simplified: &Simplified,
    engine: &mut dyn InstancedEngine,
    quality: Quality,
    solve: F,
) -> Result<TimeSeries>
where
    F: FnMut(&Scene, &Simplified, &dyn RayEngine, f32, Quality) -> Result<IndirectSolution>,
{
    let start = Instant::now();
    let limits = Thresholds::for_quality(quality);
    let progress = ProgressBar::new_spinner().with_style(
        ProgressStyle::with_template("{spinner} radiosity: {pos} solves, {elapsed} {msg}")
            .expect("progress template is valid"),
    );
    let mut d = Decomposer {
        scene,
        simplified,
        engine,
        quality,
        limits,
        solve,
        progress: &progress,
        solutions: Vec::new(),
        stats: DecomposeStats {
            max_depth: limits.max_depth,
            ..DecomposeStats::default()
        },
    };
    let a = scene.animation;
    if scene.is_static() || a.end.partial_cmp(&a.start) != Some(std::cmp::Ordering::Greater) {
        d.stats.static_scene = scene.is_static();
        d.solve_at(a.start)?;
    } else {
        let s0 = d.solve_at(a.start)?;
        let s1 = d.solve_at(a.end)?;
        d.bisect(a.start, s0, a.end, s1, 0)?;
    }
    progress.finish_and_clear();
    let mut solutions = d.solutions;
    let mut stats = d.stats;
    solutions.sort_by(|x, y| x.time.total_cmp(&y.time));
    stats.solves = solutions.len();
    stats.seconds = start.elapsed().as_secs_f64();
    Ok(TimeSeries {
        times: solutions.iter().map(|s| s.time).collect(),
        solutions,
        quality,
        stats,
    })
}

struct Decomposer<'a, F> {
    scene: &'a Scene,
    simplified: &'a Simplified,
    engine: &'a mut dyn InstancedEngine,
    quality: Quality,
    limits: Thresholds,
    solve: F,
    progress: &'a ProgressBar,
    /// Solutions in the order solved.
    solutions: Vec<IndirectSolution>,
    stats: DecomposeStats,
}

impl<F> Decomposer<'_, F>
where
    F: FnMut(&Scene, &Simplified, &dyn RayEngine, f32, Quality) -> Result<IndirectSolution>,
{
    /// Solves at `t` and returns the solution's index.
    fn solve_at(&mut self, t: f32) -> Result<usize> {
        self.progress.set_message(format!("solving at t = {t}"));
        self.engine
            .set_transforms(&self.scene.at(t))
            .with_context(|| format!("posing the scene at t = {t}"))?;
        let s = (self.solve)(self.scene, self.simplified, &*self.engine, t, self.quality)
            .with_context(|| format!("radiosity at t = {t}"))?;
        let n = self.simplified.records.len();
        ensure!(
            s.indirect.len() == n,
            "radiosity at t = {t} gave {} irradiance values for {n} records",
            s.indirect.len()
        );
        if let Some(i) = s.indirect.iter().position(|e| !e.is_finite()) {
            anyhow::bail!(
                "radiosity at t = {t}: record {i} has irradiance {}",
                s.indirect[i]
            );
        }
        self.progress.inc(1);
        self.solutions.push(s);
        Ok(self.solutions.len() - 1)
    }

    fn bisect(&mut self, t0: f32, s0: usize, t1: f32, s1: usize, depth: u32) -> Result<()> {
        let (rms, unchanged) = compare(
            &self.solutions[s0].indirect,
            &self.solutions[s1].indirect,
            self.limits.relative_rms,
        );
        let incoherent =
            rms > self.limits.relative_rms || unchanged < self.limits.unchanged_fraction;
        let tm = 0.5 * (t0 + t1);
        // Stop where f32 time can no longer be halved.
        let split = incoherent && depth < self.limits.max_depth && tm > t0 && tm < t1;
        self.stats.intervals.push(IntervalTest {
            t0,
            t1,
            depth,
            relative_rms: rms,
            unchanged,
            split,
        });
        self.stats.depth = self.stats.depth.max(depth);
        if split {
            let sm = self.solve_at(tm)?;
            self.bisect(t0, s0, tm, sm, depth + 1)?;
            self.bisect(tm, sm, t1, s1, depth + 1)?;
        }
        Ok(())
    }
}
