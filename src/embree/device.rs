//! The Embree device and the translation of Embree's error state into
//! `anyhow` errors.

use std::cell::RefCell;
use std::ffi::{c_char, c_void, CStr};
use std::ptr::{self, NonNull};
use std::sync::Arc;

use anyhow::{bail, Result};

use super::raw;

/// A handle to one Embree device. Cloning shares the device; Embree releases
/// it when the last clone and every scene built on it are gone. Scenes hold a
/// clone, so a scene can be moved between threads and stored in structs
/// without borrowing the device.
#[derive(Clone)]
pub struct Device {
    handle: Arc<DeviceHandle>,
}

struct DeviceHandle(NonNull<raw::RTCDeviceTy>);

// SAFETY: Embree devices are internally synchronized: creating scenes and
// geometries on one device from several threads is allowed, error codes are
// kept per thread, and the release may happen on any thread.
unsafe impl Send for DeviceHandle {}
// SAFETY: as for `Send`; no method of `DeviceHandle` mutates Rust-side state.
unsafe impl Sync for DeviceHandle {}

impl Drop for DeviceHandle {
    fn drop(&mut self) {
        // SAFETY: the pointer came from a successful `rtcNewDevice` and this
        // is the one reference this handle owns.
        unsafe { raw::rtcReleaseDevice(self.0.as_ptr()) }
    }
}

thread_local! {
    /// Embree's message for the first error not yet reported on this thread.
    /// Embree calls the error function on the thread that made the failing
    /// call, which is the thread that then asks `rtcGetDeviceError`.
    static LAST_MESSAGE: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// Records Embree's message for `Device::check`. Must not unwind: it is
/// called from C.
unsafe extern "C" fn record_error(_user: *mut c_void, _code: raw::RTCError, msg: *const c_char) {
    let text = if msg.is_null() {
        String::new()
    } else {
        // SAFETY: Embree passes a NUL-terminated string valid for this call.
        unsafe { CStr::from_ptr(msg) }
            .to_string_lossy()
            .into_owned()
    };
    let _ = LAST_MESSAGE.try_with(|m| {
        if let Ok(mut m) = m.try_borrow_mut() {
            m.get_or_insert(text);
        }
    });
}

impl Device {
    /// Creates a device with Embree's default configuration.
    pub fn new() -> Result<Self> {
        // SAFETY: a null config string asks for the defaults.
        let raw = unsafe { raw::rtcNewDevice(ptr::null()) };
        let Some(raw) = NonNull::new(raw) else {
            // SAFETY: with a null device Embree reports the error of the last
            // failed device creation on this thread.
            let code = unsafe { raw::rtcGetDeviceError(ptr::null_mut()) };
            bail!("Embree could not create a device: {}", error_name(code));
        };
        let handle = Arc::new(DeviceHandle(raw));
        // SAFETY: the device is valid; `record_error` does not unwind and
        // ignores the user pointer.
        unsafe {
            raw::rtcSetDeviceErrorFunction(raw.as_ptr(), Some(record_error), ptr::null_mut())
        };
        Ok(Self { handle })
    }

    pub(super) fn as_raw(&self) -> raw::RTCDevice {
        self.handle.0.as_ptr()
    }

    /// Turns the error Embree recorded for this thread since the last check
    /// into an error naming `what` was being done. Call right after the
    /// Embree calls it covers, on the same thread.
    pub(super) fn check(&self, what: impl FnOnce() -> String) -> Result<()> {
        // SAFETY: the device is valid; this reads and clears the calling
        // thread's error code.
        let code = unsafe { raw::rtcGetDeviceError(self.as_raw()) };
        let message = LAST_MESSAGE.with(|m| m.borrow_mut().take());
        if code == raw::RTCError::RTC_ERROR_NONE {
            return Ok(());
        }
        let message = message.unwrap_or_default();
        bail!(
            "Embree failed to {}: {} ({message})",
            what(),
            error_name(code)
        )
    }
}

fn error_name(code: raw::RTCError) -> &'static str {
    match code {
        raw::RTCError::RTC_ERROR_NONE => "no error",
        raw::RTCError::RTC_ERROR_INVALID_ARGUMENT => "invalid argument",
        raw::RTCError::RTC_ERROR_INVALID_OPERATION => "invalid operation",
        raw::RTCError::RTC_ERROR_OUT_OF_MEMORY => "out of memory",
        raw::RTCError::RTC_ERROR_UNSUPPORTED_CPU => "unsupported CPU",
        raw::RTCError::RTC_ERROR_CANCELLED => "cancelled",
        _ => "unknown error",
    }
}
