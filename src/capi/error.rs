//! One error model: a status for the caller's `switch`, a message kept per
//! thread for people, and the panic boundary every exported body runs in.

use std::any::Any;
use std::cell::RefCell;
use std::ffi::c_char;
use std::panic::{catch_unwind, AssertUnwindSafe};

use super::status::rw_status;

thread_local! {
    static LAST_ERROR: RefCell<String> = const { RefCell::new(String::new()) };
}

/// A failed call: its status and what went wrong.
#[derive(Debug)]
pub(crate) struct Failure {
    pub status: rw_status,
    pub message: String,
}

impl Failure {
    pub fn new(status: rw_status, message: impl Into<String>) -> Self {
        Self {
            status,
            message: message.into(),
        }
    }

    pub fn invalid(message: impl Into<String>) -> Self {
        Self::new(rw_status::RW_INVALID_ARGUMENT, message)
    }

    /// An error of a stage whose own failures are `status`: I/O errors
    /// anywhere in its chain are `RW_IO`, a cancelled bake `RW_CANCELLED`.
    pub fn of(status: rw_status, e: anyhow::Error) -> Self {
        let status = if e.chain().any(|c| c.is::<crate::bake::Cancelled>()) {
            rw_status::RW_CANCELLED
        } else if e.chain().any(is_io) {
            rw_status::RW_IO
        } else {
            status
        };
        Self::new(status, format!("{e:#}"))
    }
}

/// Whether `e` says a file could not be read or written: an error of the
/// OS, or one of the OpenImageIO shim, which does nothing but read and
/// write image files and whose failures (a full disk among them) arrive as
/// C++ exceptions carrying the OS's reason in words, not as
/// `std::io::Error`.
fn is_io(e: &(dyn std::error::Error + 'static)) -> bool {
    #[cfg(feature = "oiio")]
    if e.is::<cxx::Exception>() {
        return true;
    }
    e.is::<std::io::Error>()
}

/// Runs an exported function's body: a failure or a panic becomes its
/// status, with the message kept for [`rw_last_error`].
pub(crate) fn guard(body: impl FnOnce() -> Result<(), Failure>) -> rw_status {
    let failure = match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => return rw_status::RW_OK,
        Ok(Err(f)) => f,
        Err(payload) => Failure::new(
            rw_status::RW_PANIC,
            format!("rangewalk panicked: {}", panic_message(&*payload)),
        ),
    };
    LAST_ERROR.with(|e| *e.borrow_mut() = failure.message);
    failure.status
}

fn panic_message(payload: &(dyn Any + Send)) -> &str {
    if let Some(s) = payload.downcast_ref::<&str>() {
        s
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s
    } else {
        "(no message)"
    }
}

/// Copies the message of this thread's last failed call into `buf` (at
/// most `len - 1` bytes, cut at a character boundary, then a NUL) and
/// returns the message's full length in bytes without the NUL, so a caller
/// can size its buffer with `rw_last_error(NULL, 0) + 1`. Successful calls
/// leave the message as it was; before any failure it is empty.
///
/// # Safety
/// `buf` is NULL or points to `len` writable bytes.
#[no_mangle]
pub unsafe extern "C" fn rw_last_error(buf: *mut c_char, len: usize) -> usize {
    LAST_ERROR.with(|e| {
        let message = e.borrow();
        if !buf.is_null() && len > 0 {
            let mut n = message.len().min(len - 1);
            while !message.is_char_boundary(n) {
                n -= 1;
            }
            // SAFETY: the caller gives `len` writable bytes at `buf`;
            // `n + 1 <= len`, and a Rust string never overlaps them.
            unsafe {
                std::ptr::copy_nonoverlapping(message.as_ptr(), buf.cast::<u8>(), n);
                *buf.add(n) = 0;
            }
        }
        message.len()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An exported body that panics, as a bug in the library would.
    extern "C" fn panicking() -> rw_status {
        guard(|| panic!("forced for the test"))
    }

    fn last_error() -> String {
        let mut buf = [0 as c_char; 256];
        // SAFETY: `buf` holds `buf.len()` writable bytes.
        let n = unsafe { rw_last_error(buf.as_mut_ptr(), buf.len()) };
        let bytes: Vec<u8> = buf[..n].iter().map(|&c| c as u8).collect();
        String::from_utf8(bytes).unwrap()
    }

    #[test]
    fn a_panic_becomes_rw_panic_with_its_message_and_the_next_call_works() {
        assert_eq!(panicking(), rw_status::RW_PANIC);
        assert_eq!(last_error(), "rangewalk panicked: forced for the test");
        assert_eq!(guard(|| Ok(())), rw_status::RW_OK);
        assert_eq!(
            guard(|| Err(Failure::invalid("after the panic"))),
            rw_status::RW_INVALID_ARGUMENT
        );
        assert_eq!(last_error(), "after the panic");
    }
}
