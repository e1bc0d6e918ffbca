//! The experiments that reproduce the paper's tables, each measuring a
//! stage against path-traced references and writing a report.

pub mod common;
pub mod indirect;
pub mod motion;
pub mod views;
pub mod walkthrough;
