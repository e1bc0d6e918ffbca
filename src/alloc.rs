//! Allocations whose size the user chooses (a frame's size, its subpixels),
//! made so that one too large for memory is an error that says how much
//! was needed. Rust's ordinary allocation aborts the process instead
//! ("memory allocation of N bytes failed"), which neither the CLI's user
//! nor a C caller of the library can act on, and which no panic boundary
//! catches.

use anyhow::{anyhow, Result};

/// A byte count as people read it: "12.9 GB", "640 MB", "12 bytes".
pub fn bytes(n: u64) -> String {
    const UNITS: [(u64, &str); 3] = [(1_000_000_000, "GB"), (1_000_000, "MB"), (1_000, "kB")];
    for (unit, name) in UNITS {
        if n >= unit {
            return format!("{:.1} {name}", n as f64 / unit as f64);
        }
    }
    format!("{n} bytes")
}

/// The bytes `n` values of `T` take (saturating: a count that overflows
/// needs more than any machine has, which the message then says).
pub fn size_of_n<T>(n: usize) -> u64 {
    (n as u64).saturating_mul(std::mem::size_of::<T>() as u64)
}

/// Makes room in `v` for `n` values in all, or fails saying that `what`
/// needs that many bytes. A `v` that already holds `n` is left alone.
pub fn reserve<T>(v: &mut Vec<T>, n: usize, what: impl FnOnce() -> String) -> Result<()> {
    let more = n.saturating_sub(v.len());
    v.try_reserve_exact(more).map_err(|_| {
        anyhow!(
            "{} needs {} ({n} values of {} bytes) and the allocation failed: \
             the machine or the process's memory limit has less free",
            what(),
            bytes(size_of_n::<T>(n)),
            std::mem::size_of::<T>()
        )
    })
}

/// `v` resized to `n` copies of `value`, room made by [`reserve`].
pub fn resize<T: Clone>(
    v: &mut Vec<T>,
    n: usize,
    value: T,
    what: impl FnOnce() -> String,
) -> Result<()> {
    reserve(v, n, what)?;
    v.resize(n, value);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_counts_read_as_people_write_them() {
        assert_eq!(bytes(12), "12 bytes");
        assert_eq!(bytes(12_884_901_888), "12.9 GB");
        assert_eq!(bytes(3_221_225_472), "3.2 GB");
        assert_eq!(bytes(640_000_000), "640.0 MB");
    }

    #[test]
    fn an_impossible_allocation_is_an_error_naming_its_size() {
        let mut v: Vec<u64> = Vec::new();
        let e = reserve(&mut v, usize::MAX / 4, || "a test buffer".into()).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.starts_with("a test buffer needs ") && msg.contains("values of 8 bytes"),
            "{msg}"
        );
        resize(&mut v, 3, 7, || unreachable!()).unwrap();
        assert_eq!(v, [7, 7, 7]);
    }
}
