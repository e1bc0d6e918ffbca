//! Arguments from C checked before use: NULL pointers, paths, buffer
//! sizes, option structs that may come from an older or newer header.

use std::ffi::{c_char, CStr};
use std::path::PathBuf;

use super::error::Failure;
use crate::image::MAX_SIDE;

/// How the C caller names a field of an options struct: `options->spp`.
pub(crate) fn field(name: &str) -> String {
    format!("options->{name}")
}

/// A NUL-terminated UTF-8 path.
///
/// # Safety
/// `p` is NULL or a NUL-terminated string that outlives the call.
pub(crate) unsafe fn path(p: *const c_char, what: &str) -> Result<PathBuf, Failure> {
    // SAFETY: passed on from the caller's promise.
    unsafe { string(p, what) }.map(PathBuf::from)
}

/// A NUL-terminated, non-empty UTF-8 string.
///
/// # Safety
/// As [`path`].
pub(crate) unsafe fn string(p: *const c_char, what: &str) -> Result<String, Failure> {
    if p.is_null() {
        return Err(Failure::invalid(format!("`{what}` is NULL")));
    }
    // SAFETY: not NULL, and NUL-terminated by the caller's promise.
    let s = unsafe { CStr::from_ptr(p) };
    let s = s
        .to_str()
        .map_err(|_| Failure::invalid(format!("`{what}` is not UTF-8: {s:?}")))?;
    if s.is_empty() {
        return Err(Failure::invalid(format!("`{what}` is empty")));
    }
    Ok(s.to_owned())
}

/// The object a handle points to.
///
/// # Safety
/// `p` is NULL or a live handle of type `T` for as long as `'a`.
pub(crate) unsafe fn handle<'a, T>(p: *const T, what: &str) -> Result<&'a T, Failure> {
    // SAFETY: a live handle by the caller's promise, or NULL (refused).
    unsafe { p.as_ref() }.ok_or_else(|| Failure::invalid(format!("`{what}` is NULL")))
}

/// A plain-data input struct.
///
/// # Safety
/// `p` is NULL or points to a readable `T`.
pub(crate) unsafe fn value<T: Copy>(p: *const T, what: &str) -> Result<T, Failure> {
    // SAFETY: readable by the caller's promise, or NULL (refused).
    unsafe { p.as_ref() }
        .copied()
        .ok_or_else(|| Failure::invalid(format!("`{what}` is NULL")))
}

/// Checks an out-parameter before any work is done.
pub(crate) fn out<T>(p: *mut T, what: &str) -> Result<(), Failure> {
    if p.is_null() {
        return Err(Failure::invalid(format!("`{what}` is NULL")));
    }
    Ok(())
}

/// The number of floats of a `width`×`height` image with `channels` per
/// pixel, refusing empty, oversized and overflowing sizes.
pub(crate) fn floats(width: u32, height: u32, channels: usize) -> Result<usize, Failure> {
    if width == 0 || height == 0 {
        return Err(Failure::invalid(format!(
            "image size {width}x{height} has no pixels"
        )));
    }
    if width > MAX_SIDE || height > MAX_SIDE {
        return Err(Failure::invalid(format!(
            "image size {width}x{height} exceeds {MAX_SIDE} pixels a side"
        )));
    }
    (width as usize)
        .checked_mul(height as usize)
        .and_then(|n| n.checked_mul(channels))
        .ok_or_else(|| Failure::invalid(format!("image size {width}x{height} overflows")))
}

/// Copies `values` into the caller's buffer of exactly their length.
///
/// # Safety
/// `dst` points to `values.len()` writable floats that no Rust reference
/// aliases.
pub(crate) unsafe fn write(dst: *mut f32, values: &[f32]) {
    // SAFETY: by the caller's promise, `dst` holds `values.len()` floats
    // and does not overlap memory owned by Rust.
    unsafe { std::ptr::copy_nonoverlapping(values.as_ptr(), dst, values.len()) }
}

/// Copies `values` into the caller's buffer of `3 * values.len()` floats,
/// red, green, blue a pixel, with no copy of a frame's size in between
/// (a large frame's flat copy is an allocation that may fail).
///
/// # Safety
/// `dst` points to `3 * values.len()` writable floats that no Rust
/// reference aliases.
pub(crate) unsafe fn write_rgb(dst: *mut f32, values: &[glam::Vec3]) {
    const _: () = assert!(std::mem::size_of::<glam::Vec3>() == 3 * std::mem::size_of::<f32>());
    // SAFETY: `Vec3` is `#[repr(C)]` { x, y, z: f32 } with no padding (the
    // size assertion above), so `values` is `3 * len` floats in a row; by
    // the caller's promise `dst` holds that many and does not overlap
    // memory owned by Rust.
    unsafe { std::ptr::copy_nonoverlapping(values.as_ptr().cast::<f32>(), dst, 3 * values.len()) }
}

/// An options struct that starts with its `struct_size`: the bytes the
/// caller's header knew of are read, the rest keep `defaults`, so a
/// program built against an older header still works.
///
/// # Safety
/// `p` is NULL (then `defaults` is returned) or points to `struct_size`
/// readable bytes that begin with a `u32` `struct_size`; every field of `T`
/// is valid for any bit pattern.
pub(crate) unsafe fn sized<T: Copy>(p: *const T, defaults: T, what: &str) -> Result<T, Failure> {
    if p.is_null() {
        return Ok(defaults);
    }
    // SAFETY: `p` points to a struct that begins with a `u32` (caller's
    // promise), aligned as `T` is.
    let size = unsafe { p.cast::<u32>().read() } as usize;
    let full = std::mem::size_of::<T>();
    if size < std::mem::size_of::<u32>() || size > full {
        return Err(Failure::invalid(format!(
            "`{what}->struct_size` is {size}; this library's struct has {full} bytes (set it to sizeof the struct of the header you build with, and link the library that header came from)"
        )));
    }
    let mut out = defaults;
    // SAFETY: `size <= size_of::<T>()` bytes are readable at `p` (caller's
    // promise) and writable in `out`; any bit pattern is a valid field.
    unsafe {
        std::ptr::copy_nonoverlapping(p.cast::<u8>(), (&mut out as *mut T).cast::<u8>(), size);
    }
    Ok(out)
}
