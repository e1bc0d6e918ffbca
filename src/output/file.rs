//! Files written whole or not at all: each goes to a hidden temporary
//! beside its target (same folder, so the rename is atomic) and is renamed
//! over the target only once written. A failed write removes its
//! temporary; a killed one leaves a name [`temporary_for`] recognises, so
//! the next run can tell it from a user's file and remove it.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use anyhow::{Context, Result};

/// The suffix of every temporary.
const SUFFIX: &str = ".partial";

/// Runs `write` on a fresh temporary beside `target` and renames it over
/// `target` on success; removes it on failure. Every writer names its
/// format explicitly, so the temporary needs no extension.
pub fn write_with(target: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let tmp = temporary(target)?;
    let result = write(&tmp).and_then(|()| {
        std::fs::rename(&tmp, target)
            .with_context(|| format!("cannot rename {} to it", tmp.display()))
    });
    if result.is_err() {
        // The temporary may not exist (the write failed before creating
        // it); the error that matters is the one being returned.
        let _ = std::fs::remove_file(&tmp);
    }
    result.with_context(|| format!("writing {}", target.display()))
}

/// Writes `bytes` to `target` through a temporary, as [`write_with`].
pub fn write_file(target: &Path, bytes: impl AsRef<[u8]>) -> Result<()> {
    write_with(target, |tmp| {
        std::fs::write(tmp, bytes.as_ref()).with_context(|| format!("writing {}", tmp.display()))
    })
}

/// `.<name>.<pid>.<stamp>.partial` beside `target`. The stamp is the time
/// in nanoseconds plus a counter, so that writers on different nodes of a
/// shared filesystem (where process ids repeat) and threads of one
/// process never share a temporary.
fn temporary(target: &Path) -> Result<PathBuf> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = target
        .file_name()
        .with_context(|| format!("writing {}: the path names no file", target.display()))?;
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    let stamp = nanos.wrapping_add(COUNTER.fetch_add(1, Ordering::Relaxed));
    let mut tmp = OsString::from(".");
    tmp.push(name);
    tmp.push(format!(".{}.{stamp}{SUFFIX}", std::process::id()));
    Ok(target.with_file_name(tmp))
}

/// The file name a temporary left by [`write_with`] was for, if `name` is
/// one (`.frame-0001.exr.812.1733568000000000000.partial` was for
/// `frame-0001.exr`).
pub fn temporary_for(name: &str) -> Option<&str> {
    let inner = name.strip_prefix('.')?.strip_suffix(SUFFIX)?;
    let (rest, stamp) = inner.rsplit_once('.')?;
    let (target, pid) = rest.rsplit_once('.')?;
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    (digits(stamp) && digits(pid) && !target.is_empty()).then_some(target)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporaries_are_recognised_and_named_for_their_target() {
        let d = tempfile::tempdir().unwrap();
        let target = d.path().join("frame-0001.exr");
        let tmp = temporary(&target).unwrap();
        let name = tmp.file_name().unwrap().to_str().unwrap();
        assert_eq!(temporary_for(name), Some("frame-0001.exr"));
        assert_ne!(
            tmp,
            temporary(&target).unwrap(),
            "two temporaries share a name"
        );
        for not in [
            "frame-0001.exr",
            "frame.partial",
            ".frame.partial",
            ".frame.exr.x.1.partial",
            "..1.2.partial",
        ] {
            assert_eq!(temporary_for(not), None, "{not}");
        }
    }

    #[test]
    fn a_failed_write_leaves_neither_target_nor_temporary() {
        let d = tempfile::tempdir().unwrap();
        let target = d.path().join("plan.json");
        std::fs::write(&target, "old").unwrap();
        let e = write_with(&target, |tmp| {
            std::fs::write(tmp, "half")?;
            anyhow::bail!("disk full")
        })
        .unwrap_err();
        assert!(format!("{e:#}").contains("plan.json"), "{e:#}");
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "old");
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 1);
        write_file(&target, "new").unwrap();
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "new");
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 1);
    }
}
