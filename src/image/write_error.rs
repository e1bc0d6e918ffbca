//! What a failed write means for the person who asked for the file. The
//! OS's own words ("No space left on device (os error 28)") say neither
//! that the disk is full nor what to do; the OpenImageIO shim
//! (`os_error` in `ffi/oiio.cc`) words the same errors the same way, so a
//! message does not depend on the build.

use std::io::{Error, ErrorKind};

/// The error in words, with what to do where there is something to do.
pub fn describe(e: &Error) -> String {
    match e.kind() {
        ErrorKind::StorageFull => {
            "no space left on the device (the disk is full): free some space or write elsewhere"
                .into()
        }
        ErrorKind::QuotaExceeded => {
            "disk quota exceeded: free some space or write elsewhere".into()
        }
        ErrorKind::FileTooLarge => "file too large for this file system: write elsewhere".into(),
        _ => e.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_disk_is_named_as_such() {
        // ENOSPC on Linux.
        let full = describe(&Error::from_raw_os_error(28));
        assert!(full.contains("disk is full"), "{full}");
        let other = describe(&Error::from_raw_os_error(13));
        assert!(other.contains("ermission denied"), "{other}");
    }
}
