//! Result codes and the library's version.

use std::ffi::c_char;

/// What a call did. The values are stable within a release; link the
/// exact version the header came from.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum rw_status {
    RW_OK = 0,
    /// A NULL pointer, a size of zero or too large, a value out of range.
    RW_INVALID_ARGUMENT = 1,
    /// A file could not be read or written.
    RW_IO = 2,
    /// The scene description is invalid.
    RW_SCENE = 3,
    /// A bake is unfinished, damaged, of another scene or settings.
    RW_BAKE = 4,
    /// The progress callback asked to stop.
    RW_CANCELLED = 5,
    /// A bug: the library panicked (the message says where).
    RW_PANIC = 6,
    /// Rendering or synthesizing a frame failed.
    RW_RENDER = 7,
}

/// The name of a status (`"RW_OK"`, ...), a static string; `"RW_UNKNOWN"`
/// for a value that is none.
#[no_mangle]
pub extern "C" fn rw_status_name(status: u32) -> *const c_char {
    let name: &'static [u8] = match status {
        0 => b"RW_OK\0",
        1 => b"RW_INVALID_ARGUMENT\0",
        2 => b"RW_IO\0",
        3 => b"RW_SCENE\0",
        4 => b"RW_BAKE\0",
        5 => b"RW_CANCELLED\0",
        6 => b"RW_PANIC\0",
        7 => b"RW_RENDER\0",
        _ => b"RW_UNKNOWN\0",
    };
    name.as_ptr().cast()
}

/// The library's version (`"0.1.0"`), a static string.
#[no_mangle]
pub extern "C" fn rw_version() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
}
