//! Image error against references and the experiments that reproduce the
//! paper's tables.

pub mod flip;
pub mod metrics;
pub mod plot;
pub mod report;
