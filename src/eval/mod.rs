//! Image error against references (LRMS and its relatives, FLIP), the
//! walk's reference checks, and the experiments that reproduce the
//! paper's tables.

pub mod experiments;
pub mod flip;
pub mod metrics;
pub mod reference;
pub mod sheet;
pub mod walkcheck;
