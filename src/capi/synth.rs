//! `rw_synth`: frames from a bake, as `rangewalk synth` makes them.

use super::args::{self, field};
use super::bake::rw_bake;
use super::error::{guard, Failure};
use super::status::rw_status;
use super::view::rw_view;
use crate::synth::{Blend, Fill, Filter, Kept, Options, Synthesizer, TimeInterp, DEFAULT_BUDGET};

/// Hole filling (`rangewalk synth --fill`).
#[repr(u32)]
pub enum rw_fill {
    RW_FILL_NONE = 0,
    RW_FILL_FOREGROUND = 1,
    RW_FILL_BACKGROUND = 2,
    RW_FILL_BOTH = 3,
}

/// Interpolation between base times (`--time-interp`).
#[repr(u32)]
pub enum rw_time_interp {
    RW_TIME_INTERP_LINEAR = 0,
    RW_TIME_INTERP_MOTION = 1,
    RW_TIME_INTERP_RESHADE = 2,
}

/// Blending of samples within the depth tolerance (`--blend`).
#[repr(u32)]
pub enum rw_blend {
    RW_BLEND_AVERAGE = 0,
    RW_BLEND_NEAREST = 1,
}

/// Which frame pixels a splat reaches (`--filter`).
#[repr(u32)]
pub enum rw_filter {
    RW_FILTER_BOX = 0,
    RW_FILTER_COVER = 1,
}

/// The options of `rangewalk synth`. Start from `rw_synth_options_default`
/// (NULL gives the defaults) and set `struct_size` to
/// `sizeof(rw_synth_options)`; fields beyond a smaller `struct_size` keep
/// their defaults. Every other field is used as given.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct rw_synth_options {
    pub struct_size: u32,
    /// An `rw_fill`.
    pub fill: u32,
    /// An `rw_time_interp`.
    pub time_interp: u32,
    /// Base views to project, nearest first (at least 1).
    pub bases: u32,
    /// An `rw_blend`.
    pub blend: u32,
    /// Relative depth tolerance of the z-buffer, in (0, 1).
    pub tolerance: f32,
    /// Farthest a background fill carries a value, in pixels (at most 65535).
    pub fill_reach: u32,
    /// Light samples per pixel when re-shading, where the light changed
    /// since the base times, 1 to 256 (each is three shadow rays a pixel).
    pub reshade_samples: u32,
    /// Rays per side of a pixel at or beside a light or a silhouette
    /// against the sky, 0 to 32 (32² rays resolve a pixel's share of a
    /// light to a thousandth); 0 keeps lights and silhouettes as
    /// reprojected.
    pub light_rays: u32,
    pub seed: u64,
    /// Memory for the bases each synthesizing thread keeps, in MiB.
    pub base_memory_mib: u64,
    /// Subpixels per side each frame pixel is synthesized from, 1 to 4
    /// (1: none); only the splatting fills use them.
    pub supersample: u32,
    /// An `rw_filter`: `RW_FILTER_COVER` takes a quarter to a third off a
    /// frame's time for a somewhat higher LRMS (docs/synthesis.md).
    pub filter: u32,
}

impl Default for rw_synth_options {
    fn default() -> Self {
        let o = Options::default();
        Self {
            struct_size: std::mem::size_of::<Self>() as u32,
            fill: match o.fill {
                Fill::None => rw_fill::RW_FILL_NONE,
                Fill::Foreground => rw_fill::RW_FILL_FOREGROUND,
                Fill::Background => rw_fill::RW_FILL_BACKGROUND,
                Fill::Both => rw_fill::RW_FILL_BOTH,
            } as u32,
            time_interp: match o.time_interp {
                TimeInterp::Linear => rw_time_interp::RW_TIME_INTERP_LINEAR,
                TimeInterp::Motion => rw_time_interp::RW_TIME_INTERP_MOTION,
                TimeInterp::Reshade => rw_time_interp::RW_TIME_INTERP_RESHADE,
            } as u32,
            bases: o.bases as u32,
            blend: match o.blend {
                Blend::Average => rw_blend::RW_BLEND_AVERAGE,
                Blend::Nearest => rw_blend::RW_BLEND_NEAREST,
            } as u32,
            tolerance: o.tolerance,
            fill_reach: o.fill_reach.into(),
            reshade_samples: o.reshade_samples,
            light_rays: o.light_rays,
            seed: o.seed,
            base_memory_mib: (DEFAULT_BUDGET >> 20) as u64,
            supersample: o.supersample,
            filter: match o.filter {
                Filter::Box => rw_filter::RW_FILTER_BOX,
                Filter::Cover => rw_filter::RW_FILTER_COVER,
            } as u32,
        }
    }
}

impl rw_synth_options {
    /// The synthesis options, validated for frames of `size`, and the
    /// memory budget in bytes.
    fn options(&self, size: (u32, u32)) -> Result<(Options, usize), Failure> {
        let bad = |field: &str, value: String, want: &str| {
            Failure::invalid(format!("options->{field} {value} {want}"))
        };
        let fill = match self.fill {
            0 => Fill::None,
            1 => Fill::Foreground,
            2 => Fill::Background,
            3 => Fill::Both,
            v => return Err(bad("fill", v.to_string(), "is not an rw_fill")),
        };
        let time_interp = match self.time_interp {
            0 => TimeInterp::Linear,
            1 => TimeInterp::Motion,
            2 => TimeInterp::Reshade,
            v => {
                return Err(bad(
                    "time_interp",
                    v.to_string(),
                    "is not an rw_time_interp",
                ))
            }
        };
        let blend = match self.blend {
            0 => Blend::Average,
            1 => Blend::Nearest,
            v => return Err(bad("blend", v.to_string(), "is not an rw_blend")),
        };
        let filter = match self.filter {
            0 => Filter::Box,
            1 => Filter::Cover,
            v => return Err(bad("filter", v.to_string(), "is not an rw_filter")),
        };
        let fill_reach = u16::try_from(self.fill_reach)
            .map_err(|_| bad("fill_reach", self.fill_reach.to_string(), "exceeds 65535"))?;
        let budget = usize::try_from(self.base_memory_mib)
            .ok()
            .and_then(|m| m.checked_mul(1 << 20))
            .ok_or_else(|| {
                bad(
                    "base_memory_mib",
                    self.base_memory_mib.to_string(),
                    "overflows",
                )
            })?;
        let options = Options {
            supersample: self.supersample,
            fill,
            time_interp,
            bases: self.bases as usize,
            blend,
            tolerance: self.tolerance,
            fill_reach,
            reshade_samples: self.reshade_samples,
            light_rays: self.light_rays,
            seed: self.seed,
            filter,
        };
        options
            .validate(size, &field)
            .map_err(|e| Failure::invalid(format!("{e:#}")))?;
        Ok((options, budget))
    }
}

/// Writes the defaults (those of `rangewalk synth`), `struct_size`
/// included, into `*options`.
///
/// # Safety
/// `options` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn rw_synth_options_default(options: *mut rw_synth_options) -> rw_status {
    guard(|| {
        args::out(options, "options")?;
        // SAFETY: checked not NULL; writable by the caller's promise.
        unsafe { options.write(rw_synth_options::default()) };
        Ok(())
    })
}

/// `rw_synth_with` with the defaults of `rangewalk synth`: the frame that
/// `rangewalk synth <dir> --time <time> --size <width>x<height>` writes for
/// a camera of this view.
///
/// # Safety
/// As [`rw_synth_with`].
#[no_mangle]
pub unsafe extern "C" fn rw_synth(
    bake: *const rw_bake,
    view: *const rw_view,
    time: f32,
    width: u32,
    height: u32,
    rgb: *mut f32,
    distance: *mut f32,
) -> rw_status {
    // SAFETY: passed on as the caller promises; NULL options are the
    // defaults.
    unsafe {
        rw_synth_with(
            bake,
            view,
            time,
            width,
            height,
            std::ptr::null(),
            rgb,
            distance,
        )
    }
}

/// Synthesizes `view` at `time` from the bake's base images into `rgb`
/// (`width * height` RGB triples of linear radiance, rows top to bottom)
/// and, unless it is NULL, `distance` (`width * height` distances from the
/// camera along each pixel's centre ray; 0 where no base saw a surface).
/// `options` NULL: the defaults. Thread-safe: any number of threads may
/// synthesize from one bake at once.
///
/// # Safety
/// `bake` is NULL or a live bake; `view` NULL or readable; `options` NULL
/// or readable for its `struct_size` bytes; `rgb` NULL or
/// `width * height * 3` writable floats; `distance` NULL or
/// `width * height` writable floats.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn rw_synth_with(
    bake: *const rw_bake,
    view: *const rw_view,
    time: f32,
    width: u32,
    height: u32,
    options: *const rw_synth_options,
    rgb: *mut f32,
    distance: *mut f32,
) -> rw_status {
    guard(|| {
        // SAFETY: as the caller promises.
        let handle = unsafe { args::handle(bake, "bake") }?;
        // SAFETY: as the caller promises.
        let view = unsafe { args::value(view, "view") }?;
        // SAFETY: as the caller promises.
        let options = unsafe { args::sized(options, rw_synth_options::default(), "options") }?;
        args::out(rgb, "rgb")?;
        args::floats(width, height, 3)?;
        handle
            .scene
            .check_time(time)
            .map_err(|e| Failure::invalid(format!("{e:#}")))?;
        let (options, budget) = options.options((width, height))?;
        let camera = view.camera(width, height)?;
        let kept = {
            let mut pool = handle.kept.lock().unwrap_or_else(|e| e.into_inner());
            match pool.iter().position(|k| k.budget() == budget) {
                Some(i) => pool.swap_remove(i),
                None => Kept::new(budget),
            }
        };
        let mut synth = Synthesizer::resume(&handle.scene, &handle.bake, kept);
        let frame = synth.frame(&camera, time, &options);
        let kept = synth.suspend();
        handle
            .kept
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(kept);
        let (frame, _) = frame.map_err(|e| Failure::of(rw_status::RW_RENDER, e))?;
        // SAFETY: `rgb` is not NULL and holds width * height * 3 floats,
        // three for each of the frame's pixels (caller's promise).
        unsafe { args::write_rgb(rgb, &frame.radiance) };
        if !distance.is_null() {
            // SAFETY: not NULL, and holds width * height floats, the
            // frame's pixel count (caller's promise).
            unsafe { args::write(distance, &frame.distance) };
        }
        Ok(())
    })
}
