//! rangewalk: global illumination for animated scenes computed once, stored as
//! time sequences of range images at a few base viewpoints, and re-used to
//! synthesize frames along any walk-through path in a view space.
//!
//! The pipeline and the module boundaries are described in `DESIGN.md` of the
//! project; this crate's modules follow it one to one.
//!
//! The `cli` feature (on by default) adds what only the command line, the
//! experiments and the viewer need; the C library is built without it.
//!
//! `unsafe` lives only at the two foreign boundaries, Embree (`embree`,
//! private: no bindgen type reaches the public API) and OpenImageIO
//! (`image::oiio`); everywhere else it is refused by the compiler, and
//! every `unsafe` block there says why it holds.
#![deny(unsafe_code)]
#![deny(clippy::undocumented_unsafe_blocks)]

pub mod accel;
pub mod alloc;
pub mod bake;
pub mod bsdf;
pub mod camera;
#[allow(unsafe_code)]
pub mod capi;
pub mod checksum;
#[cfg(feature = "embree")]
#[allow(unsafe_code)]
mod embree;
#[cfg(feature = "cli")]
pub mod eval;
pub mod export;
pub mod image;
pub mod output;
pub mod plan;
pub mod progress;
pub mod quality;
pub mod radiosity;
pub mod ray;
pub mod render;
pub mod rng;
pub mod scene;
pub mod synth;
#[cfg(feature = "cli")]
pub mod viewer;
