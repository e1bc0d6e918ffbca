//! Image error against references and the experiments that reproduce the
//! paper's tables.

pub mod experiment;
pub mod flip;
pub mod metrics;
pub mod motion;
pub mod plot;
pub mod reference;
pub mod report;
mod staging;
pub mod summary;
pub mod synthesis;
pub mod views;
pub mod walkcheck;
pub mod walkthrough;
