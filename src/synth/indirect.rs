//! The diffuse indirect light of a frame's pixels at the frame's time, as
//! the bake's radiosity records give it. Reprojection carries each base
//! pixel's indirect light from its base time; a surface seen at only one
//! of two base times (what a moving object uncovered) keeps that time's
//! light while the pixels beside it blend both, and a seam shows where
//! they meet. Re-shading adds the records' change between the pixel's
//! base times and the frame's time, a control variate like its direct
//! light: looked up, not sampled, so it adds no noise, and at a base time
//! it is exactly zero.
//!
//! Records are looked up in object space, where a point on a rigidly
//! moving object stays put. A record set's irradiance at `t` is linear
//! between the two solutions that bracket it ([`TimeSeries::indirect_at`]),
//! and so is a lookup in it, but for the few records whose extrapolation
//! turns negative; a lookup at `t` is therefore the same blend of the two
//! solutions' lookups, and one cache per solution serves every frame.

use std::path::Path;
use std::sync::OnceLock;

use anyhow::{Context, Result};
use glam::Vec3;

use crate::bake::manifest::RADIOSITY;
use crate::radiosity::lookup::IrradianceCache;
use crate::radiosity::store as radiosity_store;
use crate::radiosity::temporal::TimeSeries;
use crate::radiosity::Simplified;
use crate::render::surface::DiffuseQuery;
use crate::scene::Scene;

/// A bake's radiosity solutions, each searchable once first asked for.
pub struct Records {
    simplified: Simplified,
    series: TimeSeries,
    caches: Vec<OnceLock<Result<IrradianceCache, String>>>,
}

impl Records {
    /// The records of the bake in `dir`, which must have been solved for
    /// `scene`.
    pub fn load(dir: &Path, scene: &Scene) -> Result<Self> {
        let path = dir.join(RADIOSITY);
        let (simplified, series, _) = radiosity_store::load_for(&path, scene, None)
            .with_context(|| format!("reading the radiosity records of {}", dir.display()))?;
        let caches = series.solutions.iter().map(|_| OnceLock::new()).collect();
        Ok(Self {
            simplified,
            series,
            caches,
        })
    }

    fn cache(&self, k: usize) -> Result<&IrradianceCache> {
        self.caches[k]
            .get_or_init(|| {
                IrradianceCache::new(&self.simplified, &self.series.solutions[k].indirect)
                    .map_err(|e| format!("{e:#}"))
            })
            .as_ref()
            .map_err(|e| anyhow::anyhow!("radiosity solution at t = {}: {e}", self.series.times[k]))
    }

    /// The solutions bracketing `t` and the weight of the later one (held
    /// outside the first and last, as [`TimeSeries::indirect_at`]).
    fn bracket(&self, t: f32) -> (usize, usize, f32) {
        let times = &self.series.times;
        let last = times.len() - 1;
        if t.is_nan() || t <= times[0] {
            return (0, 0, 0.0);
        }
        if t >= times[last] {
            return (last, last, 0.0);
        }
        let k = times.partition_point(|&s| s <= t) - 1;
        let w = ((t - times[k]) / (times[k + 1] - times[k])).clamp(0.0, 1.0);
        (k, k + 1, w)
    }

    /// Builds the caches of the solutions bracketing every time in
    /// `times`, in parallel, before pixels look them up.
    pub fn prepare(&self, times: &[f32]) -> Result<()> {
        use rayon::prelude::*;
        let mut wanted: Vec<usize> = times
            .iter()
            .flat_map(|&t| {
                let (a, b, _) = self.bracket(t);
                [a, b]
            })
            .collect();
        wanted.sort_unstable();
        wanted.dedup();
        wanted
            .par_iter()
            .try_for_each(|&k| self.cache(k).map(|_| ()))
    }

    /// Indirect irradiance at the query's point at time `t`.
    pub fn irradiance(&self, q: &DiffuseQuery, t: f32) -> Result<Vec3> {
        let (a, b, w) = self.bracket(t);
        let at = |k: usize| -> Result<Vec3> {
            Ok(self
                .cache(k)?
                .irradiance(q.object, q.front, q.local, q.normal))
        };
        let ea = at(a)?;
        if w == 0.0 || a == b {
            return Ok(ea);
        }
        Ok(ea + (at(b)? - ea) * w)
    }

    /// Whether any record's light changes over the animation: a static
    /// scene (one solution) needs no correction.
    pub fn vary(&self) -> bool {
        self.series.solutions.len() > 1
    }
}
