//! What the experiments share: options and cached bakes and references,
//! synthesized frames measured against references, the path tracer's
//! convergence, and the report's tables, plots and folder.

pub mod convergence;
pub mod plot;
pub mod sequence;
pub mod setup;
pub mod staging;
pub mod synthesize;
pub mod table;
