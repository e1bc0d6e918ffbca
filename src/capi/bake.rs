//! Bakes: running one as `rangewalk bake` does, and opening a finished one
//! for synthesis.

use std::ffi::{c_char, c_void};
use std::sync::Mutex;

use super::args::{self, field};
use super::error::{guard, Failure};
use super::scene::rw_scene;
use super::status::rw_status;
use crate::accel::{self, Backend};
use crate::bake::{self, Bake, BaseProjection, IndirectSource, Sampling, Shard};
use crate::plan::{self, PlanOptions};
use crate::quality::Quality;
use crate::scene::Scene;
use crate::synth::{self, Kept};

/// Base image projection (`rangewalk bake --projection`).
#[repr(u32)]
pub enum rw_projection {
    RW_PROJECTION_SPHERE = 0,
    RW_PROJECTION_FISHEYE = 1,
}

/// Where diffuse indirect light comes from (`rangewalk bake --indirect`).
#[repr(u32)]
pub enum rw_indirect {
    RW_INDIRECT_RADIOSITY = 0,
    RW_INDIRECT_PATH = 1,
    RW_INDIRECT_GATHER = 2,
}

/// The options of `rangewalk bake`. Start from `rw_bake_options_default`
/// (or pass NULL for the defaults) and set `struct_size` to
/// `sizeof(rw_bake_options)`: fields beyond a smaller `struct_size` keep
/// their defaults.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct rw_bake_options {
    pub struct_size: u32,
    /// In [0, 1], used as given (`--quality`; the default is 0.5).
    pub quality: f32,
    /// Side of the square base images; 0: sized for `frame_width` x
    /// `frame_height` frames at the scene's narrowest field of view.
    pub size: u32,
    /// Samples per base pixel; 0: the CLI's default, 16.
    pub spp: u32,
    pub seed: u64,
    /// Size of the frames to be synthesized; 0: the CLI's 512.
    pub frame_width: u32,
    pub frame_height: u32,
    /// An `rw_projection`.
    pub projection: u32,
    /// An `rw_indirect`.
    pub indirect: u32,
    /// Longest path as Mitsuba's `max_depth`; 0: unlimited.
    pub max_depth: u32,
    /// Bake only every `shard_count`-th image from the `shard_index`-th;
    /// `shard_count` 0 or 1: every image.
    pub shard_index: u32,
    pub shard_count: u32,
    /// Relative standard error of a base pixel's mean luminance at which
    /// it stops taking samples (`--noise`; 0.02: 2 %); 0: the CLI's
    /// default, 0.02. `spp` is the least a pixel takes.
    pub noise: f32,
    /// Most samples a base pixel takes (`--max-spp`); 0: 16 × `spp`.
    /// Equal to `spp`: every pixel takes `spp` samples.
    pub max_spp: u32,
}

impl Default for rw_bake_options {
    fn default() -> Self {
        let (frame_width, frame_height) =
            crate::image::parse_size(bake::DEFAULT_FRAME_SIZE).expect("a valid default size");
        Self {
            struct_size: std::mem::size_of::<Self>() as u32,
            quality: Quality::DEFAULT.get(),
            size: 0,
            spp: bake::DEFAULT_SPP,
            seed: 0,
            frame_width,
            frame_height,
            projection: rw_projection::RW_PROJECTION_SPHERE as u32,
            indirect: match IndirectSource::default() {
                IndirectSource::Radiosity => rw_indirect::RW_INDIRECT_RADIOSITY,
                IndirectSource::Path => rw_indirect::RW_INDIRECT_PATH,
                IndirectSource::Gather => rw_indirect::RW_INDIRECT_GATHER,
            } as u32,
            max_depth: 0,
            shard_index: 0,
            shard_count: 1,
            noise: bake::sampling::DEFAULT_NOISE,
            max_spp: 0,
        }
    }
}

/// Writes the defaults, `struct_size` included, into `*options`.
///
/// # Safety
/// `options` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn rw_bake_options_default(options: *mut rw_bake_options) -> rw_status {
    guard(|| {
        args::out(options, "options")?;
        // SAFETY: checked not NULL; writable by the caller's promise.
        unsafe { options.write(rw_bake_options::default()) };
        Ok(())
    })
}

/// The settings, sampling and shard of a bake from C's options.
fn settings(
    scene: &Scene,
    o: &rw_bake_options,
) -> Result<(bake::Settings, Sampling, Shard), Failure> {
    let quality =
        Quality::new(o.quality).map_err(|e| Failure::invalid(format!("options->quality: {e}")))?;
    let projection = match o.projection {
        0 => BaseProjection::Sphere,
        1 => BaseProjection::Fisheye,
        p => {
            return Err(Failure::invalid(format!(
                "options->projection {p} is not an rw_projection"
            )))
        }
    };
    let indirect = match o.indirect {
        0 => IndirectSource::Radiosity,
        1 => IndirectSource::Path,
        2 => IndirectSource::Gather,
        i => {
            return Err(Failure::invalid(format!(
                "options->indirect {i} is not an rw_indirect"
            )))
        }
    };
    let defaults = rw_bake_options::default();
    let or = |v: u32, d: u32| if v == 0 { d } else { v };
    let frame = (
        or(o.frame_width, defaults.frame_width),
        or(o.frame_height, defaults.frame_height),
    );
    args::floats(frame.0, frame.1, 1).map_err(|f| {
        Failure::invalid(format!("options->frame_width, frame_height: {}", f.message))
    })?;
    let size = (o.size != 0).then_some(o.size);
    let (size, _) = bake::size::resolve(scene, size, projection, frame, &|f| match f {
        "frame_size" => "options->frame_width, frame_height".into(),
        f => field(f),
    })
    .map_err(|e| Failure::invalid(format!("{e:#}")))?;
    let shard = match o.shard_count {
        0 | 1 if o.shard_index == 0 => Shard::ALL,
        n if o.shard_index < n => Shard {
            index: o.shard_index,
            count: n,
        },
        n => {
            return Err(Failure::invalid(format!(
                "options->shard_index {} is not below shard_count {n}",
                o.shard_index
            )))
        }
    };
    let spp = or(o.spp, defaults.spp);
    let noise = if o.noise == 0.0 {
        defaults.noise
    } else {
        o.noise
    };
    let sampling = Sampling {
        noise: Some(noise),
        max_spp: (o.max_spp != 0).then_some(o.max_spp),
    };
    sampling
        .check(spp, &field)
        .map_err(|e| Failure::invalid(format!("{e:#}")))?;
    let settings = bake::Settings {
        quality,
        size,
        spp,
        projection,
        indirect,
        seed: o.seed,
        backend: Backend::default_available(),
        max_depth: (o.max_depth != 0).then_some(o.max_depth),
        planning: bake::Planning::default(),
    };
    Ok((settings, sampling, shard))
}

/// Reports a bake's progress, on the thread that called `rw_bake_run`:
/// `fraction` of this run's images finished (0 once planning and radiosity
/// are done, then after each image). Return false to stop the bake before
/// its next image (`rw_bake_run` then returns `RW_CANCELLED`; running it
/// again resumes).
pub type rw_progress_fn =
    Option<unsafe extern "C" fn(userdata: *mut c_void, fraction: f32) -> bool>;

/// Plans, solves radiosity and renders the base images of the scene into
/// the bake directory `dir`, as `rangewalk bake <scene> --out <dir>` does
/// with `options` (NULL: the defaults), or resumes the unfinished bake in
/// `dir` (which must have been started with the same scene and options).
/// `progress` may be NULL. Returns `RW_OK` when this run's images are done
/// (with shards, the bake is complete when every shard's are).
/// Thread-safe. One directory takes one bake at a time (shards of one bake
/// together): a second run on images a running one renders, in this or
/// another process, returns `RW_BAKE` naming the holder's process.
///
/// # Safety
/// `scene` is NULL or a live scene; `options` NULL or readable for its
/// `struct_size` bytes; `dir` NULL or a NUL-terminated string; `progress`
/// NULL or a function that may be called with `userdata`.
#[no_mangle]
pub unsafe extern "C" fn rw_bake_run(
    scene: *const rw_scene,
    options: *const rw_bake_options,
    dir: *const c_char,
    progress: rw_progress_fn,
    userdata: *mut c_void,
) -> rw_status {
    guard(|| {
        // SAFETY: as the caller promises.
        let scene = &unsafe { args::handle(scene, "scene") }?.scene;
        // SAFETY: as the caller promises.
        let options = unsafe { args::sized(options, rw_bake_options::default(), "options") }?;
        // SAFETY: as the caller promises.
        let dir = unsafe { args::path(dir, "dir") }?;
        let (settings, sampling, shard) = settings(scene, &options)?;
        let failed = |e| Failure::of(rw_status::RW_BAKE, e);
        let mut engine = accel::build(
            settings.backend,
            &scene.geometry(),
            &scene.at(scene.animation.start),
        )
        .map_err(failed)?;
        let plan_options = PlanOptions {
            quality: settings.quality,
            resolution: settings.planning.resolution,
            master_list: settings.planning.master_list,
            view_fitness: settings.planning.view_fitness,
        };
        let mut observe = |fraction: f32| match progress {
            // SAFETY: the caller gives a function that takes `userdata`.
            Some(f) => unsafe { f(userdata, fraction) },
            None => true,
        };
        bake::run_observed(
            scene,
            &dir,
            &settings,
            &sampling,
            shard,
            engine.as_mut(),
            |e| plan::make(scene, e, &plan_options),
            &mut observe,
        )
        .map_err(failed)?;
        Ok(())
    })
}

/// A finished bake with the scene it was made from (opaque). `rw_synth`
/// may run on one bake from several threads at once; each thread keeps the
/// base images it read (up to `base_memory_mib` each) for its next frame.
pub struct rw_bake {
    pub(crate) scene: Scene,
    pub(crate) bake: Bake,
    /// What synthesizers kept between calls, one per thread that was
    /// synthesizing at once.
    pub(crate) kept: Mutex<Vec<Kept>>,
}

fn handle(scene: Scene, bake: Bake) -> *mut rw_bake {
    Box::into_raw(Box::new(rw_bake {
        scene,
        bake,
        kept: Mutex::new(Vec::new()),
    }))
}

/// Opens the complete bake in `dir` with the scene its manifest names, as
/// `rangewalk synth <dir>` does; refuses an unfinished bake or one whose
/// scene has changed since. On success `*out` owns the bake, to be
/// released with `rw_bake_free`.
///
/// # Safety
/// `dir` is NULL or a NUL-terminated string; `out` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn rw_bake_open(dir: *const c_char, out: *mut *mut rw_bake) -> rw_status {
    guard(|| {
        // SAFETY: as the caller promises.
        let dir = unsafe { args::path(dir, "dir") }?;
        args::out(out, "out")?;
        let (scene, bake) =
            synth::open(&dir, None).map_err(|e| Failure::of(rw_status::RW_BAKE, e))?;
        // SAFETY: checked not NULL; writable by the caller's promise.
        unsafe { out.write(handle(scene, bake)) };
        Ok(())
    })
}

/// Opens the complete bake in `dir` for `scene` (a copy is kept: the
/// scene may be freed after), as `rangewalk synth <dir> --scene` does;
/// refuses a bake of another scene, saying what differs.
///
/// # Safety
/// `scene` is NULL or a live scene; otherwise as [`rw_bake_open`].
#[no_mangle]
pub unsafe extern "C" fn rw_bake_open_with_scene(
    scene: *const rw_scene,
    dir: *const c_char,
    out: *mut *mut rw_bake,
) -> rw_status {
    guard(|| {
        // SAFETY: as the caller promises.
        let scene = &unsafe { args::handle(scene, "scene") }?.scene;
        // SAFETY: as the caller promises.
        let dir = unsafe { args::path(dir, "dir") }?;
        args::out(out, "out")?;
        let failed = |e| Failure::of(rw_status::RW_BAKE, e);
        let bake = Bake::open(&dir, scene).map_err(failed)?;
        synth::check_bake(&bake).map_err(failed)?;
        // SAFETY: checked not NULL; writable by the caller's promise.
        unsafe { out.write(handle(scene.clone(), bake)) };
        Ok(())
    })
}

/// Releases a bake; NULL is a no-op.
///
/// # Safety
/// `bake` is NULL or a bake from `rw_bake_open*` not yet freed, which no
/// other thread is using.
#[no_mangle]
pub unsafe extern "C" fn rw_bake_free(bake: *mut rw_bake) {
    if !bake.is_null() {
        // SAFETY: made by `Box::into_raw` in `handle`, freed once (caller's
        // promise).
        drop(unsafe { Box::from_raw(bake) });
    }
}
