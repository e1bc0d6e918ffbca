//! The plan of an opened bake: its base views and their time lists, for
//! pipelines that schedule their own frames or shards around them.

use super::args;
use super::bake::rw_bake;
use super::error::{guard, Failure};
use super::status::rw_status;

/// Writes the number of base views of the bake's plan into `*count`.
///
/// # Safety
/// `bake` is NULL or a live bake; `count` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn rw_bake_view_count(bake: *const rw_bake, count: *mut usize) -> rw_status {
    guard(|| {
        // SAFETY: as the caller promises.
        let bake = unsafe { args::handle(bake, "bake") }?;
        args::out(count, "count")?;
        // SAFETY: checked not NULL; writable by the caller's promise.
        unsafe { count.write(bake.bake.manifest.plan.views.len()) };
        Ok(())
    })
}

/// Base view `view` of the plan: its position into `position` (3 floats),
/// the number of its base times into `*time_count`, and, unless `times` is
/// NULL, the first `min(times_len, *time_count)` of those times (seconds,
/// ascending) into `times`. Thread-safe.
///
/// # Safety
/// `bake` is NULL or a live bake; `position` NULL or 3 writable floats;
/// `times` NULL or `times_len` writable floats; `time_count` NULL or
/// writable.
#[no_mangle]
pub unsafe extern "C" fn rw_bake_view(
    bake: *const rw_bake,
    view: usize,
    position: *mut f32,
    times: *mut f32,
    times_len: usize,
    time_count: *mut usize,
) -> rw_status {
    guard(|| {
        // SAFETY: as the caller promises.
        let bake = unsafe { args::handle(bake, "bake") }?;
        args::out(position, "position")?;
        args::out(time_count, "time_count")?;
        let views = &bake.bake.manifest.plan.views;
        let v = views.get(view).ok_or_else(|| {
            Failure::invalid(format!(
                "view {view} is not below the plan's {} views",
                views.len()
            ))
        })?;
        // SAFETY: `position` is not NULL and holds 3 floats (caller's
        // promise).
        unsafe { args::write(position, &v.position.to_array()) };
        if !times.is_null() {
            let n = times_len.min(v.times.len());
            // SAFETY: not NULL and holds `times_len >= n` floats.
            unsafe { args::write(times, &v.times[..n]) };
        }
        // SAFETY: checked not NULL; writable by the caller's promise.
        unsafe { time_count.write(v.times.len()) };
        Ok(())
    })
}
