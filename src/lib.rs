//! rangewalk: global illumination for animated scenes computed once, stored as
//! time sequences of range images at a few base viewpoints, and re-used to
//! synthesize frames along any walk-through path in a view space.
//!
//! The pipeline and the module boundaries are described in `DESIGN.md` of the
//! project; this crate's modules follow it one to one.

pub mod accel;
pub mod bake;
pub mod camera;
#[allow(unsafe_code)]
pub mod capi;
#[cfg(feature = "embree")]
pub mod embree;
pub mod eval;
pub mod export;
pub mod image;
pub mod plan;
pub mod radiosity;
pub mod render;
pub mod scene;
pub mod synth;
