//! An entry point that panics on purpose, so that C tests can check the
//! panic boundary (`RW_PANIC` and its message, nothing unwound into C).

use std::ffi::c_char;

use super::args;
use super::error::guard;
use super::status::rw_status;

/// For tests of the panic boundary only: panics with `message` inside the
/// library and returns `RW_PANIC` (`RW_INVALID_ARGUMENT` if `message` is
/// NULL).
///
/// # Safety
/// `message` is NULL or a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn rw_test_panic(message: *const c_char) -> rw_status {
    guard(|| {
        // SAFETY: as the caller promises.
        let message = unsafe { args::string(message, "message") }?;
        panic!("{message}");
    })
}
