//! The bake directory: simplified scene, time list and solutions on disk.

use std::path::Path;

use anyhow::Result;

use super::temporal::TimeSeries;
use super::Simplified;

/// Writes `simplified` and `series` under `dir` (created if needed).
pub fn save(dir: &Path, simplified: &Simplified, series: &TimeSeries) -> Result<()> {
    let _ = (dir, simplified, series);
    todo!("bake save")
}

/// Reads back what [`save`] wrote, identical to what was saved.
pub fn load(dir: &Path) -> Result<(Simplified, TimeSeries)> {
    let _ = dir;
    todo!("bake load")
}
