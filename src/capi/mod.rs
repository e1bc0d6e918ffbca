//! The C ABI (`include/rangewalk.h`, generated from this module by
//! cbindgen): C and C++ pipelines load a scene, render, bake and synthesize
//! in-process through opaque handles, with the command line's defaults.
//!
//! Conventions (those of rustls-ffi): every name starts with `rw_`; every
//! fallible call returns an [`status::rw_status`] and writes its outputs
//! only on success; [`error::rw_last_error`] gives the message of the
//! calling thread's last failure; every pointer is checked for NULL; no
//! panic crosses the boundary (each body runs under `catch_unwind`, a panic
//! becomes `RW_PANIC`). `docs/c-api.md` describes ownership and threading.

#![allow(non_camel_case_types)]

mod args;
pub mod bake;
pub mod error;
pub mod plan;
pub mod render;
pub mod scene;
pub mod status;
pub mod synth;
pub mod view;
