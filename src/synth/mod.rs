//! Walk-through synthesis (paper §4.5): frames for any camera in the view
//! space at any time, made from the base range images of a bake by view
//! reprojection (`pinterp`'s semantics: z-buffer with a relative depth
//! tolerance, nearest-first or ray-angle-weighted blending, foreground and
//! background fill) and interpolation in time: per pixel between the two
//! base times bracketing the frame's (`pcomb`, the paper's), with every
//! sample moved by its object's rigid motion (motion-compensated), or that
//! and direct light evaluated again at the frame's time (re-shaded).

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, ensure, Context, Result};
use glam::{Affine3A, Vec3};
use rayon::prelude::*;

use crate::accel::{self, InstancedEngine};
use crate::alloc;
use crate::bake::Bake;
use crate::camera::Camera;
use crate::image::{RangeImage, RangeMeta, NO_HIT};
use crate::scene::{Scene, ViewSpace};

pub mod base;
mod cells;
mod fill;
mod indirect;
mod lights;
mod reshade;
pub mod walk;
mod warp;

pub use base::{Base, BaseCache, BYTES_PER_PIXEL};
use indirect::Records;
use warp::{Accum, Pass, Target, Twin, WarpSettings, SKY_Z};
pub use warp::{Blend, Filter};

#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    serde::Serialize,
    strum::Display,
    strum::EnumString,
    strum::IntoStaticStr,
    strum::VariantArray,
    strum::EnumMessage,
)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum Fill {
    /// A base pixel lands on at most one frame pixel; holes stay empty.
    None,
    /// Each base pixel covers the parallelogram to its right and lower
    /// neighbours' projections, where their depths agree.
    Foreground,
    /// Holes take the farther of their nearest filled neighbours.
    Background,
    /// Foreground, then background.
    Both,
}

#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    serde::Serialize,
    strum::Display,
    strum::EnumString,
    strum::IntoStaticStr,
    strum::VariantArray,
    strum::EnumMessage,
)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum TimeInterp {
    /// Each time's frame projected alone, blended per pixel (the paper's).
    Linear,
    /// Samples moved by their object's motion to the frame's time and
    /// projected together.
    Motion,
    /// Motion-compensated, with the diffuse direct light evaluated again at
    /// the frame's time and mirrors traced again.
    Reshade,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    pub fill: Fill,
    pub time_interp: TimeInterp,
    /// How many base views, nearest first.
    pub bases: usize,
    pub blend: Blend,
    /// Relative depth tolerance (pinterp's `-t`, default 0.02).
    pub tolerance: f32,
    /// Farthest a background fill carries a value, in pixels.
    pub fill_reach: u16,
    /// Light samples per pixel when re-shading, where the light changed
    /// since the base times (elsewhere [`reshade::FIND_SAMPLES`] find that
    /// it did not).
    pub reshade_samples: u32,
    /// Rays per side of a pixel at or beside a light or a silhouette
    /// against the sky ([`lights`]); 0: none.
    pub light_rays: u32,
    pub seed: u64,
    /// Side of the grid of subpixels each frame pixel is synthesized as
    /// and then averaged from (1: none). A z-buffer gives each of its
    /// pixels one surface, so a pixel a silhouette crosses shows the
    /// nearer surface whole where the reference shows both by the share
    /// each covers: thin objects thicken and close the gaps between them.
    /// Subpixels resolve that share. Only splatting fills (`foreground`,
    /// `both`) use them.
    pub supersample: u32,
    /// Which pixels a splat reaches (see [`Filter`]).
    pub filter: Filter,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            fill: Fill::Both,
            time_interp: TimeInterp::Motion,
            bases: 4,
            blend: Blend::Average,
            tolerance: 0.02,
            fill_reach: 32,
            reshade_samples: 64,
            light_rays: 8,
            seed: 1,
            supersample: 2,
            filter: Filter::Box,
        }
    }
}

/// The most rays per side of a pixel at a light's rim ([`lights`]): 32²
/// rays resolve the share of a pixel a light covers to a thousandth, finer
/// than any preview or error measure shows, at about a thousand rays for
/// each rim pixel; 100,000 asked for 10¹⁰ rays a pixel and never finished.
pub const MAX_LIGHT_RAYS: u32 = 32;

/// The most light samples a pixel takes when re-shading: three sets of
/// shadow rays a pixel (one for the frame's time and one for each base
/// time), so 256 traces some 200 million rays for a 512² frame, more than
/// path tracing it at a few samples a pixel: beyond that re-shading is no
/// longer what synthesis is for.
pub const MAX_RESHADE_SAMPLES: u32 = 256;

/// The most base views a frame projects: each gives a pass per base time
/// it takes (two at most), and a z-buffer entry names its pass in
/// [`warp::MAX_PASSES`].
pub const MAX_BASES: usize = warp::MAX_PASSES / 2;

/// The most subpixels a frame is synthesized at: the pixels a range image
/// may hold ([`crate::image::MAX_PIXELS`], 8192²). A subpixel's z-buffer
/// entry alone takes 48 bytes, so this is about 3.2 GB before the frame.
pub const MAX_SUBPIXELS: u64 = crate::image::MAX_PIXELS;

impl Options {
    /// Refuses values that make no frame or unbounded work. `name` turns a
    /// field's name (`light_rays`) into what the caller calls it (the
    /// flag `--light-rays`, the C field `options->light_rays`), so that
    /// each front end reports its own names from one set of limits.
    pub fn check(&self, name: &dyn Fn(&str) -> String) -> Result<()> {
        ensure!(
            self.bases > 0,
            "{} 0: synthesis needs at least 1 base view",
            name("bases")
        );
        ensure!(
            self.bases <= MAX_BASES,
            "{} {} must lie in 1..={MAX_BASES}",
            name("bases"),
            self.bases
        );
        ensure!(
            self.tolerance > 0.0 && self.tolerance < 1.0,
            "{} {} must lie in (0, 1): it is the relative depth difference within which samples join",
            name("tolerance"),
            self.tolerance
        );
        ensure!(
            (1..=MAX_RESHADE_SAMPLES).contains(&self.reshade_samples),
            "{} {} must lie in 1..={MAX_RESHADE_SAMPLES}: each sample is three shadow rays a pixel, \
             and more than {MAX_RESHADE_SAMPLES} costs more than path tracing the frame",
            name("reshade_samples"),
            self.reshade_samples
        );
        ensure!(
            self.light_rays <= MAX_LIGHT_RAYS,
            "{} {} must lie in 0..={MAX_LIGHT_RAYS}: it is rays per side of each pixel at a light's rim \
             ({}² of them), and {MAX_LIGHT_RAYS}² already resolve a pixel's share of the light to a thousandth",
            name("light_rays"),
            self.light_rays,
            self.light_rays
        );
        ensure!(
            (1..=MAX_SUPERSAMPLE).contains(&self.supersample),
            "{} {} must lie in 1..={MAX_SUPERSAMPLE}",
            name("supersample"),
            self.supersample
        );
        Ok(())
    }

    /// The subpixels per side a frame is synthesized at: only splatting
    /// fills use them (see [`Options::supersample`]).
    pub fn subpixels_per_side(&self) -> u32 {
        if matches!(self.fill, Fill::Foreground | Fill::Both) {
            self.supersample
        } else {
            1
        }
    }

    /// Refuses a `width` × `height` frame whose subpixels exceed
    /// [`MAX_SUBPIXELS`]: the frame size alone does not say how much a
    /// frame holds, its supersampling squares it. `name` as in
    /// [`Options::check`].
    pub fn check_frame_size(
        &self,
        width: u32,
        height: u32,
        name: &dyn Fn(&str) -> String,
    ) -> Result<()> {
        let k = u64::from(self.subpixels_per_side());
        let n = u64::from(width) * k * u64::from(height) * k;
        ensure!(
            n <= MAX_SUBPIXELS,
            "a {width}x{height} frame at {k}x{k} supersampling ({} {k}) is {n} subpixels, more than the \
             {MAX_SUBPIXELS} (8192x8192) a frame may be synthesized at (about {} of z-buffer); \
             make the frame or {} smaller",
            name("supersample"),
            alloc::bytes(n.saturating_mul(size_of::<Accum>() as u64)),
            name("supersample")
        );
        Ok(())
    }
}

/// What making one frame took and found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Wall time, base loading included.
    pub seconds: f64,
    /// Of which reading and preparing bases.
    pub load_seconds: f64,
    /// Manifest indices of the base images used.
    pub images: Vec<usize>,
    /// Pixels no sample reached and no fill filled.
    pub holes: usize,
    /// Pixels filled by background fill.
    pub filled: usize,
    /// Cracks in surfaces repaired ([`fill::cracks`]).
    pub cracks: usize,
    /// Holes a ray found open to the sky, given its radiance (with
    /// background fill).
    pub sky: usize,
    /// Mirror pixels whose reflection no base showed (kept as projected).
    pub mirror_misses: usize,
    /// Pixels at or beside lights and silhouettes against the sky traced
    /// again.
    pub light_pixels: usize,
    /// Whether re-shading corrected diffuse indirect light by the bake's
    /// radiosity records (it cannot where the bake traced it, and need not
    /// in a static scene).
    pub indirect_corrected: bool,
    /// Pixels whose direct light changed since the base times (and their
    /// neighbours), re-shaded with all of `reshade_samples`.
    pub reshaded: usize,
    /// Base pixels nearest-first blending did not project because the
    /// frame already held nearer or equal samples wherever they could land
    /// (counted once for every band of the frame they were left out of).
    pub hidden: usize,
}

/// Frames from one bake.
pub struct Synthesizer<'a> {
    pub scene: &'a Scene,
    pub bake: &'a Bake,
    cache: BaseCache,
    /// Built on first use by re-shading or tracing lights' pixels, with
    /// the time it is posed at.
    engine: Option<(Box<dyn InstancedEngine>, f32)>,
    /// The z-buffers of the last frame, kept so that the next one does not
    /// fault in tens of megabytes of fresh pages (projection clears them).
    buffers: [Vec<Accum>; 2],
    /// A frame its caller gave back ([`Synthesizer::recycle`]).
    spare: Option<RangeImage>,
    /// The bake's radiosity records, read on the first re-shaded frame;
    /// `Some(None)` where they cannot correct anything (see
    /// [`Synthesizer::records`]).
    records: Option<Option<Arc<Records>>>,
    /// Whether nearest-first blending leaves out what cannot change a
    /// pixel ([`WarpSettings::cull`]); always, but where a test shows that
    /// leaving it out changes nothing.
    cull: bool,
}

/// Memory kept for bases by default: eight 2,600² bases fit.
pub const DEFAULT_BUDGET: usize = 1800 << 20;

/// What a synthesizer keeps from frame to frame (the bases it read, its ray
/// engine) apart from the scene and bake it borrows, so that an owner of
/// both can keep it between synthesizers: the C ABI pools these for the
/// threads that synthesize from one bake.
pub struct Kept {
    cache: BaseCache,
    engine: Option<(Box<dyn InstancedEngine>, f32)>,
    buffers: [Vec<Accum>; 2],
    records: Option<Option<Arc<Records>>>,
}

impl Kept {
    pub fn new(budget_bytes: usize) -> Self {
        Self {
            cache: BaseCache::new(budget_bytes),
            engine: None,
            buffers: Default::default(),
            records: None,
        }
    }

    /// The memory budget for bases it was made with.
    pub fn budget(&self) -> usize {
        self.cache.budget()
    }
}

impl<'a> Synthesizer<'a> {
    pub fn new(scene: &'a Scene, bake: &'a Bake, budget_bytes: usize) -> Self {
        Self::resume(scene, bake, Kept::new(budget_bytes))
    }

    /// A synthesizer that goes on from what an earlier one over the same
    /// scene and bake kept.
    pub fn resume(scene: &'a Scene, bake: &'a Bake, kept: Kept) -> Self {
        Self {
            scene,
            bake,
            cache: kept.cache,
            engine: kept.engine,
            buffers: kept.buffers,
            records: kept.records,
            spare: None,
            cull: true,
        }
    }

    /// What this synthesizer read and built, for [`Synthesizer::resume`].
    pub fn suspend(self) -> Kept {
        Kept {
            cache: self.cache,
            engine: self.engine,
            buffers: self.buffers,
            records: self.records,
        }
    }

    pub fn cache(&self) -> &BaseCache {
        &self.cache
    }

    /// Takes back a frame its caller is done with: the next frame of its
    /// size is written into its planes rather than new ones, which cost
    /// about a millisecond of a 512² frame to fault in and fill.
    pub fn recycle(&mut self, frame: RangeImage) {
        self.spare = Some(frame);
    }

    /// The recycled frame if it is `camera`'s size.
    fn spare_for(&mut self, camera: &Camera) -> Option<RangeImage> {
        self.spare
            .take_if(|i| (i.width, i.height) == (camera.width, camera.height))
    }

    /// Base views nearest `position` first, at most `count`.
    pub fn nearest_views(&self, position: Vec3, count: usize) -> Vec<usize> {
        let views = &self.bake.manifest.plan.views;
        let mut order: Vec<usize> = (0..views.len()).collect();
        order.sort_by(|&a, &b| {
            let (da, db) = (
                views[a].position.distance_squared(position),
                views[b].position.distance_squared(position),
            );
            da.total_cmp(&db).then(a.cmp(&b))
        });
        order.truncate(count.max(1));
        order
    }

    /// The images of `view` bracketing `t` and the fraction of the way from
    /// the first to the second (one image where `t` is a base time or
    /// outside the view's times).
    pub fn bracket(&self, view: usize, t: f32) -> Result<(usize, Option<(usize, f32)>)> {
        let m = &self.bake.manifest;
        let times = &m.plan.views[view].times;
        let index = |j: usize| {
            m.images
                .iter()
                .position(|e| e.view == view && e.time_index == j)
                .with_context(|| {
                    format!("the bake's manifest has no image of view {view} time {j}")
                })
        };
        ensure!(!times.is_empty(), "view {view} of the bake has no times");
        let after = times.partition_point(|&x| x <= t);
        if after == 0 {
            return Ok((index(0)?, None));
        }
        let lo = after - 1;
        if after == times.len() || times[lo] == t {
            return Ok((index(lo)?, None));
        }
        let alpha = (t - times[lo]) / (times[after] - times[lo]);
        Ok((index(lo)?, Some((index(after)?, alpha))))
    }

    /// Synthesizes the frame `camera` sees at time `t`.
    pub fn frame(
        &mut self,
        camera: &Camera,
        t: f32,
        opts: &Options,
    ) -> Result<(RangeImage, FrameStats)> {
        let field = |f: &str| format!("options.{f}");
        opts.check(&field)?;
        opts.check_frame_size(camera.width, camera.height, &field)?;
        // Without splats a sample lands on one subpixel: subpixels would
        // only thin the samples out, and a background fill would give most
        // of them the farther surface beside them.
        let k = opts.subpixels_per_side();
        if k == 1 {
            let (image, stats) = self.subpixels(camera, 1, t, opts, true)?;
            return Ok((image.expect("asked for"), stats));
        }
        let fine_camera = Camera {
            width: camera.width * k,
            height: camera.height * k,
            ..*camera
        };
        // Per-pixel counts keep their meaning per frame pixel: a
        // background fill reaches as far, re-shading traces about as many
        // rays per frame pixel. Lights' rims are traced in the frame's own
        // pixels, after: their rays resolve each pixel's share themselves.
        let fine = Options {
            fill_reach: opts.fill_reach.saturating_mul(k as u16),
            light_rays: 0,
            reshade_samples: opts.reshade_samples.div_ceil(k * k),
            ..*opts
        };
        // Re-shading works on the subpixels' surfaces; otherwise the frame
        // is averaged from the z-buffer itself.
        let reshade = opts.time_interp == TimeInterp::Reshade;
        let (fine_image, mut stats) = self.subpixels(&fine_camera, k, t, &fine, reshade)?;
        let start = Instant::now();
        let poses = self.scene.at(t);
        let spare = self.spare_for(camera);
        let buffer = &self.buffers[0];
        let seen = |j: usize| !buffer[j].is_empty();
        let (mut image, holes, mixed) = match &fine_image {
            Some(f) => downsample(
                self.scene,
                &poses,
                spare,
                (camera, k, &f.meta),
                seen,
                |j| f.radiance[j],
                |j| f.object_id[j],
                |j| {
                    (
                        f.distance[j],
                        f.object_id[j],
                        f.primitive_id[j],
                        f.normal[j],
                    )
                },
            )?,
            None => {
                let meta = self.frame_meta(&fine_camera, t, opts, stats.images.len());
                let cam = camera.position;
                downsample(
                    self.scene,
                    &poses,
                    spare,
                    (camera, k, &meta),
                    seen,
                    |j| buffer[j].radiance / buffer[j].w,
                    |j| buffer[j].object,
                    |j| surface(self.scene, &poses, cam, &buffer[j]),
                )?
            }
        };
        if opts.light_rays > 0 {
            let scene = self.scene;
            let engine = &*self.engine_at(t)?;
            stats.light_pixels =
                lights::trace(scene, engine, t, opts.light_rays, Some(&mixed), &mut image);
        }
        let per_pixel = |n: usize| n.div_ceil((k * k) as usize);
        stats.holes = holes;
        stats.filled = per_pixel(stats.filled);
        stats.sky = per_pixel(stats.sky);
        stats.mirror_misses = per_pixel(stats.mirror_misses);
        stats.reshaded = per_pixel(stats.reshaded);
        stats.seconds += start.elapsed().as_secs_f64();
        Ok((image, stats))
    }

    /// What a frame's range image says of how it was made.
    fn frame_meta(&self, camera: &Camera, t: f32, opts: &Options, images: usize) -> RangeMeta {
        RangeMeta {
            camera: *camera,
            time: t,
            scene: format!(
                "{} t={t} synthesized from {} ({:?}, fill {:?}, {} base image(s))",
                self.scene.source.display(),
                self.bake.dir.display(),
                opts.time_interp,
                opts.fill,
                images
            ),
        }
    }

    /// The frame at the camera's own resolution, its z-buffer left in
    /// `buffers[0]`; its range image only when `image` is asked for.
    /// `camera` is the frame's at `k` × `k` subpixels a pixel (for
    /// messages).
    fn subpixels(
        &mut self,
        camera: &Camera,
        k: u32,
        t: f32,
        opts: &Options,
        image: bool,
    ) -> Result<(Option<RangeImage>, FrameStats)> {
        self.scene.check_time(t)?;
        let start = Instant::now();
        let load_before = self.cache.load_seconds;
        let views = self.nearest_views(camera.position, opts.bases);
        // (manifest image, weight in time, whether it is the later time)
        let mut wanted: Vec<(usize, f32, bool)> = Vec::new();
        for &v in &views {
            let (lo, hi) = self.bracket(v, t)?;
            match hi {
                None => wanted.push((lo, 1.0, false)),
                Some((hi, alpha)) => {
                    // Nearer time first, for nearest-first blending.
                    if alpha <= 0.5 {
                        wanted.push((lo, 1.0 - alpha, false));
                        wanted.push((hi, alpha, true));
                    } else {
                        wanted.push((hi, alpha, true));
                        wanted.push((lo, 1.0 - alpha, false));
                    }
                }
            }
        }
        let keep: Vec<usize> = wanted.iter().map(|w| w.0).collect();
        let mut bases: Vec<Arc<Base>> = Vec::with_capacity(wanted.len());
        for &(k, _, _) in &wanted {
            bases.push(self.cache.get(self.bake, self.scene, k, &keep)?);
        }
        let target = Target::new(*camera);
        let background = matches!(opts.fill, Fill::Background | Fill::Both);
        let settings = WarpSettings {
            tolerance: opts.tolerance,
            splat: matches!(opts.fill, Fill::Foreground | Fill::Both),
            filter: opts.filter,
            blend: opts.blend,
            alpha: matches!(opts.time_interp, TimeInterp::Linear | TimeInterp::Reshade),
            sky: !background,
            cull: self.cull,
        };
        let poses_t = self.scene.at(t);
        let moves_of = |base: &Base| -> Vec<Option<Affine3A>> {
            if opts.time_interp == TimeInterp::Linear {
                return Vec::new();
            }
            self.scene
                .objects
                .iter()
                .zip(&poses_t)
                .map(|(o, &now)| {
                    (!o.motion.is_static()).then(|| now * o.motion.pose(base.time).inverse())
                })
                .collect()
        };
        let (w, h) = (camera.width, camera.height);
        let n = (w * h) as usize;
        let mut stats = FrameStats {
            images: keep.clone(),
            ..FrameStats::default()
        };
        // The holes a buffer has left after the sky's; background fill
        // fills some of them.
        let finish =
            |buffer: &mut Vec<Accum>, holes: usize, seen: &[fill::Seen], stats: &mut FrameStats| {
                if background && holes > 0 {
                    let filled = fill::background(buffer, w, h, opts.fill_reach, seen);
                    stats.filled += filled;
                    return holes - filled;
                }
                holes
            };
        let [mut first, mut second] = std::mem::take(&mut self.buffers);
        let frame = if k == 1 {
            format!("a {w}x{h} frame")
        } else {
            format!("a {}x{} frame at {k}x{k} supersampling", w / k, h / k)
        };
        let z_buffer = |which: &'static str| {
            let frame = &frame;
            move || format!("the {which}z-buffer of {frame}")
        };
        // Stale contents are cleared band by band as they are projected.
        alloc::resize(&mut first, n, Accum::default(), z_buffer(""))?;
        let pixels: Vec<Accum> = if opts.time_interp == TimeInterp::Linear {
            // pinterp per time, then pcomb: two frames blended per pixel.
            alloc::resize(&mut second, n, Accum::default(), z_buffer("second "))?;
            let passes = |later: bool| -> Vec<Pass> {
                bases
                    .iter()
                    .zip(&wanted)
                    .filter(|(_, w)| w.2 == later)
                    .map(|(b, &(_, weight, _))| Pass {
                        base: b,
                        moves: Vec::new(),
                        weight: 1.0,
                        alpha: if later { weight } else { 0.0 },
                        twin: None,
                    })
                    .collect()
            };
            let (lo, hi) = (passes(false), passes(true));
            let mut holes = [0; 2];
            for (k, (passes, buffer)) in [(&lo, &mut first), (&hi, &mut second)]
                .into_iter()
                .enumerate()
            {
                let warped = warp::warp(&target, passes, &settings, buffer);
                stats.hidden += warped.hidden;
                holes[k] = warped.holes;
                stats.cracks += self.repair_cracks(camera, t, buffer, opts.tolerance)?;
                if background {
                    let (sky, seen) = self.open_to_sky(camera, t, buffer, holes[k])?;
                    stats.sky += sky;
                    holes[k] = finish(buffer, holes[k] - sky, &seen, &mut stats);
                }
            }
            first
                .par_iter_mut()
                .zip(&second)
                .for_each(|(a, b)| *a = blend_linear(a, b));
            // A pixel is a hole where both times left one.
            stats.holes = if holes.contains(&0) {
                0
            } else {
                first.par_iter().filter(|a| a.is_empty()).count()
            };
            first
        } else {
            // A sample of the other time still claims its pixel (what a
            // moving object uncovered) when nothing nearer in time does.
            let in_time = |i: usize| wanted[i].1.max(1e-3);
            // The two times of one view follow each other in `wanted`,
            // nearer first; the nearer carries what they share.
            let twin_of = |i: usize| -> Option<Twin> {
                let same = |j: usize| {
                    let (a, b) = (&bases[i], &bases[j]);
                    a.view == b.view && a.camera == b.camera
                };
                if i + 1 < bases.len() && same(i + 1) {
                    Some(Twin::Carries {
                        base: &bases[i + 1],
                        weight: in_time(i + 1),
                        alpha: bases[i + 1].time,
                    })
                } else if i > 0 && same(i - 1) {
                    Some(Twin::CarriedBy(&bases[i - 1]))
                } else {
                    None
                }
            };
            let passes: Vec<Pass> = bases
                .iter()
                .enumerate()
                .map(|(i, b)| Pass {
                    base: b,
                    moves: moves_of(b),
                    weight: in_time(i),
                    alpha: b.time,
                    twin: twin_of(i),
                })
                .collect();
            let warped = warp::warp(&target, &passes, &settings, &mut first);
            stats.hidden += warped.hidden;
            stats.holes = warped.holes;
            stats.cracks += self.repair_cracks(camera, t, &mut first, opts.tolerance)?;
            if background {
                let (sky, seen) = self.open_to_sky(camera, t, &mut first, stats.holes)?;
                stats.sky += sky;
                stats.holes = finish(&mut first, stats.holes - sky, &seen, &mut stats);
            }
            first
        };
        if !image {
            self.buffers = [pixels, second];
            stats.load_seconds = self.cache.load_seconds - load_before;
            stats.seconds = start.elapsed().as_secs_f64();
            return Ok((None, stats));
        }
        let spare = self.spare_for(camera);
        let mut image = blank(spare, self.frame_meta(camera, t, opts, bases.len()))?;
        write_pixels(self.scene, &poses_t, &pixels, &mut image);
        if opts.time_interp == TimeInterp::Reshade {
            let scene = self.scene;
            let mut times: Vec<f32> = bases.iter().map(|b| b.time).collect();
            times.sort_by(f32::total_cmp);
            times.dedup();
            let (w, cam) = (camera.width as usize, camera.position);
            // Every pixel first takes a few samples at every time, which
            // find where the light changed; there the frame's and the base
            // times' light are drawn again with all of `reshade_samples`.
            let find = reshade::FIND_SAMPLES.div_ceil(k * k);
            let plane = |what: &str| reshade::light_plane(pixels.len(), w, what);
            let mut now = plane("the frame's time")?;
            let mut then = Vec::with_capacity(times.len());
            for &time in &times {
                then.push(plane(&format!("base time {time}"))?);
            }
            // The frame's time first, then every base time.
            let all_times: Vec<f32> = std::iter::once(t).chain(times.iter().copied()).collect();
            let (mut samples, mut only) = (find, None::<Vec<bool>>);
            loop {
                for (i, &time) in all_times.iter().enumerate() {
                    let engine = &*self.engine_at(time)?;
                    let out = if i == 0 { &mut now } else { &mut then[i - 1] };
                    reshade::direct_at(
                        scene,
                        engine,
                        t,
                        time,
                        &pixels,
                        w,
                        cam,
                        samples,
                        opts.seed,
                        only.as_deref(),
                        out,
                    )?;
                }
                if only.is_some() || opts.reshade_samples <= find {
                    break;
                }
                let changed = reshade::changed(&now, &then, w, k as usize);
                stats.reshaded = changed.iter().filter(|&&c| c).count();
                (samples, only) = (opts.reshade_samples, Some(changed));
            }
            let records = self.records()?;
            if let Some(r) = &records {
                r.prepare(&all_times)?;
            }
            stats.indirect_corrected = records.is_some();
            let engine = &*self.engine_at(t)?;
            stats.mirror_misses = reshade::apply(
                scene,
                engine,
                t,
                &bases,
                &wanted.iter().map(|w| w.1).collect::<Vec<_>>(),
                &pixels,
                &times,
                &now,
                &then,
                records.as_deref(),
                k as usize,
                opts,
                &mut image,
            )?;
        }
        if opts.light_rays > 0 {
            let scene = self.scene;
            let engine = &*self.engine_at(t)?;
            // Without subpixels a pixel holds the one surface its z-buffer
            // entry kept.
            stats.light_pixels = lights::trace(scene, engine, t, opts.light_rays, None, &mut image);
        }
        self.buffers = [pixels, second];
        stats.load_seconds = self.cache.load_seconds - load_before;
        stats.seconds = start.elapsed().as_secs_f64();
        Ok((Some(image), stats))
    }

    /// Repairs the cracks of `buffer`, a frame of `camera` ([`fill::cracks`]),
    /// building the ray engine only where one may need it.
    fn repair_cracks(
        &mut self,
        camera: &Camera,
        t: f32,
        buffer: &mut [Accum],
        tolerance: f32,
    ) -> Result<usize> {
        let found = fill::cracks(buffer, camera.width, camera.height, tolerance);
        if found.is_empty() {
            return Ok(0);
        }
        let engine = &*self.engine_at(t)?;
        Ok(fill::repair_cracks(engine, camera, buffer, &found))
    }

    /// Gives the holes of `buffer` (a frame of `camera` with `holes` of
    /// them) that are open to the sky its radiance ([`fill::sky`]),
    /// building the ray engine only where a hole needs it; returns how many,
    /// and what the other holes' rays met.
    fn open_to_sky(
        &mut self,
        camera: &Camera,
        t: f32,
        buffer: &mut [Accum],
        holes: usize,
    ) -> Result<(usize, Vec<fill::Seen>)> {
        if holes == 0 {
            return Ok((0, Vec::new()));
        }
        let sky = crate::render::sky(self.scene, t);
        let engine = &*self.engine_at(t)?;
        Ok(fill::sky(engine, &sky, camera, buffer))
    }

    /// The radiosity records that re-shading corrects diffuse indirect
    /// light with: none where the bake traced its indirect light (it has
    /// none) or the scene is static (they never change).
    fn records(&mut self) -> Result<Option<Arc<Records>>> {
        if self.records.is_none() {
            let wanted =
                self.bake.manifest.settings.indirect.uses_records() && !self.scene.is_static();
            let records = if wanted {
                Some(Arc::new(Records::load(&self.bake.dir, self.scene)?))
            } else {
                None
            };
            self.records = Some(records.filter(|r| r.vary()));
        }
        Ok(self.records.clone().flatten())
    }

    /// The scene's ray engine (built on first use) posed at `t`.
    pub(crate) fn engine_at(&mut self, t: f32) -> Result<&mut dyn InstancedEngine> {
        if self.engine.is_none() {
            let backend = self.bake.manifest.settings.backend;
            let engine = accel::build(backend, &self.scene.geometry(), &self.scene.at(t))
                .with_context(|| format!("building the {backend} ray engine for synthesis"))?;
            self.engine = Some((engine, t));
        }
        let (engine, posed) = self.engine.as_mut().expect("built above");
        if *posed != t {
            engine.set_transforms(&self.scene.at(t))?;
            *posed = t;
        }
        Ok(&mut **engine)
    }
}

/// The most subpixels per side a frame pixel may be synthesized from.
pub const MAX_SUPERSAMPLE: u32 = 4;

/// A frame of `camera` (with `meta`) from its synthesis at `k` × `k`
/// subpixels a pixel: subpixel `j` was reached by some sample (`seen`),
/// holds `radiance(j)` and shows object `object(j)`, whose surface is
/// `surface(j)` (distance, object, primitive, normal). A pixel's radiance is the mean of its seen
/// subpixels; its surface that of the seen subpixel nearest its centre,
/// with the distance where its centre ray meets that surface's triangle
/// (at `poses`), as a render's would be; a pixel none reached is a hole. A
/// pixel part of which shows a light takes the light's surface, so that
/// tracing lights' rims ([`lights`]) finds it. Written into `spare`'s
/// planes where given. Returns the frame, its holes, and which pixels'
/// subpixels show more than one object (their values mix surfaces:
/// [`lights::trace`] mends them).
#[allow(clippy::too_many_arguments)]
fn downsample(
    scene: &Scene,
    poses: &[Affine3A],
    spare: Option<RangeImage>,
    (camera, k, meta): (&Camera, u32, &RangeMeta),
    seen: impl Fn(usize) -> bool + Sync,
    radiance: impl Fn(usize) -> Vec3 + Sync,
    object: impl Fn(usize) -> u32 + Sync,
    surface: impl Fn(usize) -> (f32, u32, u32, Vec3) + Sync,
) -> Result<(RangeImage, usize, Vec<bool>)> {
    let mut image = blank(
        spare,
        RangeMeta {
            camera: *camera,
            ..meta.clone()
        },
    )?;
    let (w, k) = (camera.width as usize, k as usize);
    let fw = w * k;
    let emissive = lights::emissive(scene);
    let emits = |id: u32| emissive.get(id as usize).copied().unwrap_or(false);
    // Subpixel offsets, nearest the pixel's centre first.
    let mut order: Vec<(usize, usize)> = (0..k * k).map(|i| (i % k, i / k)).collect();
    let centre = (k as f32 - 1.0) * 0.5;
    order.sort_by(|a, b| {
        let d = |p: &(usize, usize)| (p.0 as f32 - centre).powi(2) + (p.1 as f32 - centre).powi(2);
        d(a).total_cmp(&d(b))
    });
    let mut mixed = Vec::new();
    alloc::resize(&mut mixed, image.len(), false, || {
        format!("which of {} pixels mix surfaces", image.len())
    })?;
    let holes = image
        .radiance
        .par_iter_mut()
        .zip(mixed.par_iter_mut())
        .zip(image.distance.par_iter_mut())
        .zip(image.object_id.par_iter_mut())
        .zip(image.primitive_id.par_iter_mut())
        .zip(image.normal.par_iter_mut())
        .enumerate()
        .map(
            |(i, (((((pixel, mixed), distance), shown_object), primitive), normal))| {
                let (x, y) = (i % w, i / w);
                let at = |(dx, dy): (usize, usize)| (y * k + dy) * fw + x * k + dx;
                let (mut sum, mut n, mut shown, mut light) = (Vec3::ZERO, 0u32, None, None);
                for &o in &order {
                    let j = at(o);
                    if !seen(j) {
                        continue;
                    }
                    sum += radiance(j);
                    n += 1;
                    *mixed |= shown.is_some_and(|s| object(s) != object(j));
                    shown.get_or_insert(j);
                    if light.is_none() && emits(object(j)) {
                        light = Some(j);
                    }
                }
                let Some(j) = light.or(shown) else {
                    // Written, as every pixel: the image may be recycled.
                    *pixel = Vec3::ZERO;
                    (*distance, *shown_object, *primitive, *normal) =
                        (0.0, NO_HIT, NO_HIT, Vec3::ZERO);
                    return 1;
                };
                *pixel = sum / n as f32;
                (*distance, *shown_object, *primitive, *normal) = surface(j);
                if let Some(d) =
                    centre_distance(scene, poses, camera, x, y, *shown_object, *primitive)
                {
                    *distance = d;
                }
                0
            },
        )
        .sum();
    Ok((image, holes, mixed))
}

/// Distance along pixel `(x, y)`'s centre ray to the plane of `object`'s
/// triangle `primitive` posed at `poses`; `None` for sky or where the ray
/// runs along the plane or meets it behind the camera.
fn centre_distance(
    scene: &Scene,
    poses: &[Affine3A],
    camera: &Camera,
    x: usize,
    y: usize,
    object: u32,
    primitive: u32,
) -> Option<f32> {
    let mesh = &scene.objects.get(object as usize)?.mesh;
    let &[i, j, l] = mesh.triangles.get(primitive as usize)?;
    let pose = poses[object as usize];
    let p = &mesh.positions;
    let a = pose.transform_point3(p[i as usize]);
    let n =
        (pose.transform_point3(p[j as usize]) - a).cross(pose.transform_point3(p[l as usize]) - a);
    let ray = camera.ray(x as f32 + 0.5, y as f32 + 0.5)?;
    let along = ray.dir.dot(n);
    let d = (a - ray.origin).dot(n) / along;
    (along.abs() > 1e-12 * n.length() && d > 0.0 && d.is_finite()).then_some(d)
}

/// `pcomb -s (1−α) A -s α B`, where `α` is the time fraction of the views
/// that reached the pixel; a pixel only one time reached takes that time.
fn blend_linear(a: &Accum, b: &Accum) -> Accum {
    match (a.is_empty(), b.is_empty()) {
        (true, true) => *a,
        (false, true) => *a,
        (true, false) => *b,
        (false, false) => {
            // Mean fraction of the later views; the earlier ones carry 0.
            let alpha = (b.alpha / b.w).clamp(0.0, 1.0);
            let (ca, cb) = (a.radiance / a.w, b.radiance / b.w);
            let nearer = if alpha <= 0.5 { a } else { b };
            Accum {
                w: 1.0,
                radiance: ca * (1.0 - alpha) + cb * alpha,
                ..*nearer
            }
        }
    }
}

/// An image with `meta`, `spare`'s planes where given (stale: the caller
/// writes every pixel); an error saying what it needs where memory is
/// short.
fn blank(spare: Option<RangeImage>, meta: RangeMeta) -> Result<RangeImage> {
    match spare {
        Some(image) => Ok(RangeImage { meta, ..image }),
        None => RangeImage::try_empty(meta),
    }
}

/// The frame's pixels from what they gathered, every one of them written
/// (an image may come from [`Synthesizer::recycle`]).
fn write_pixels(scene: &Scene, poses: &[Affine3A], pixels: &[Accum], image: &mut RangeImage) {
    let cam = image.meta.camera.position;
    let row = image.width.max(1) as usize;
    image
        .radiance
        .par_chunks_mut(row)
        .zip(image.distance.par_chunks_mut(row))
        .zip(image.object_id.par_chunks_mut(row))
        .zip(image.primitive_id.par_chunks_mut(row))
        .zip(image.normal.par_chunks_mut(row))
        .zip(pixels.par_chunks(row))
        .for_each(
            |(((((radiance, distance), object), primitive), normal), a)| {
                // Neighbouring pixels mostly show one triangle: its normal is
                // worked out once for the run.
                let mut last: Option<((u32, u32), Option<Vec3>)> = None;
                for (j, a) in a.iter().enumerate() {
                    if a.is_empty() {
                        radiance[j] = Vec3::ZERO;
                        (distance[j], object[j], primitive[j], normal[j]) = shown(cam, a, None);
                        continue;
                    }
                    radiance[j] = a.radiance / a.w;
                    let key = (a.object, a.primitive);
                    let n = match last {
                        Some((k, n)) if k == key => n,
                        _ => {
                            let n = triangle_normal(scene, poses, a);
                            last = Some((key, n));
                            n
                        }
                    };
                    (distance[j], object[j], primitive[j], normal[j]) = shown(cam, a, n);
                }
            },
        );
}

/// The surface a pixel that gathered `a` shows: its distance, object and
/// primitive ids and the normal of its triangle at `poses`, turned towards
/// the camera at `cam`; distance 0, no ids and a zero normal for sky.
fn surface(scene: &Scene, poses: &[Affine3A], cam: Vec3, a: &Accum) -> (f32, u32, u32, Vec3) {
    shown(cam, a, triangle_normal(scene, poses, a))
}

/// The unit normal at `poses` of the triangle `a` shows, unturned; `None`
/// for sky and for a primitive its mesh does not hold.
fn triangle_normal(scene: &Scene, poses: &[Affine3A], a: &Accum) -> Option<Vec3> {
    if a.is_empty() || a.z >= SKY_Z {
        return None;
    }
    let mesh = &scene.objects[a.object as usize].mesh;
    let &[i, j, l] = mesh.triangles.get(a.primitive as usize)?;
    let p = &mesh.positions;
    let e = (p[j as usize] - p[i as usize]).cross(p[l as usize] - p[i as usize]);
    Some(
        poses[a.object as usize]
            .transform_vector3(e)
            .normalize_or_zero(),
    )
}

/// [`surface`] from the triangle's normal `n` ([`triangle_normal`]).
fn shown(cam: Vec3, a: &Accum, n: Option<Vec3>) -> (f32, u32, u32, Vec3) {
    if a.is_empty() || a.z >= SKY_Z {
        return (0.0, NO_HIT, NO_HIT, Vec3::ZERO);
    }
    let Some(n) = n else {
        return (a.z, a.object, a.primitive, Vec3::ZERO);
    };
    let n = if n.dot(cam - a.point) < 0.0 { -n } else { n };
    (a.z, a.object, a.primitive, n)
}

/// Whether `position` lies in the view space (with a relative slack for
/// rounding).
pub fn inside_view_space(space: &ViewSpace, position: Vec3) -> bool {
    let slack = 1e-4;
    match *space {
        ViewSpace::Segment { a, b } => {
            let ab = b - a;
            let s = ((position - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
            position.distance(a + ab * s) <= slack * ab.length().max(1e-12)
        }
        ViewSpace::Rectangle { min, max } | ViewSpace::Box { min, max } => {
            let pad = (max - min).max_element() * slack;
            position.cmpge(min - pad).all() && position.cmple(max + pad).all()
        }
    }
}

/// The warning for a camera outside the view space, if it is.
pub fn view_space_warning(scene: &Scene, what: &str, position: Vec3) -> Option<String> {
    let space = scene.view_space.as_ref()?;
    (!inside_view_space(space, position)).then(|| {
        format!(
            "warning: {what} at {position} is outside the scene's view space; \
             expect holes and stretched surfaces where the bases saw too little"
        )
    })
}

/// The bake in `dir` and its scene (from `scene`, else the one its
/// manifest names), checked against each other.
pub fn open(dir: &Path, scene: Option<&Path>) -> Result<(Scene, Bake)> {
    let manifest = crate::bake::Manifest::read(dir)?;
    let path = scene.map_or(manifest.scene, Path::to_path_buf);
    let scene = Scene::load(&path).with_context(|| {
        format!(
            "loading the scene of {} (pass --scene where it has moved)",
            dir.display()
        )
    })?;
    let bake = Bake::open(dir, &scene)?;
    check_bake(&bake)?;
    Ok((scene, bake))
}

/// Refuses a bake whose images are not base images this synthesis reads.
pub fn check_bake(bake: &Bake) -> Result<()> {
    if bake.manifest.plan.views.is_empty() {
        bail!("{}: the bake's plan has no views", bake.dir.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {

    use super::*;
    use crate::accel::Backend;
    use crate::bake::{self, BaseProjection, IndirectSource, Settings, Shard};
    use crate::plan::{Plan, PlannedView};

    fn cornell_box() -> Scene {
        let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("scenes/cornell-box/scene.toml");
        Scene::load(&path).unwrap()
    }

    /// A bake of three views along the Cornell box's view space at t = 0
    /// and 1 (192² sphere bases, one sample a pixel), opened, in the
    /// folder returned with it.
    fn three_view_bake(scene: &Scene) -> (tempfile::TempDir, Bake) {
        let Some(ViewSpace::Segment { a, b }) = scene.view_space else {
            panic!("the Cornell box's view space is a segment");
        };
        let plan = Plan {
            quality: 0.6,
            views: (0..3)
                .map(|i| PlannedView {
                    position: a.lerp(b, i as f32 / 2.0),
                    times: vec![0.0, 1.0],
                })
                .collect(),
            light_times: vec![0.0, 1.0],
            ..Plan::default()
        };
        let settings = Settings {
            quality: crate::quality::Quality::new(0.6).unwrap(),
            size: 192,
            spp: 1,
            projection: BaseProjection::Sphere,
            indirect: IndirectSource::Path,
            seed: 1,
            backend: Backend::default_available(),
            max_depth: Some(1),
            planning: Default::default(),
        };
        let dir = tempfile::tempdir().unwrap();
        let mut engine = accel::build(settings.backend, &scene.geometry(), &scene.at(0.0)).unwrap();
        bake::run(
            scene,
            dir.path(),
            &settings,
            Shard::ALL,
            engine.as_mut(),
            |_| Ok(plan),
        )
        .unwrap();
        let baked = Bake::open(dir.path(), scene).unwrap();
        (dir, baked)
    }

    /// Skipping the samples of later bases that cannot change a pixel is
    /// an optimisation only: frames are bit for bit those made without it,
    /// for both ways of interpolating in time and with subpixels.
    #[test]
    fn nearest_first_frames_are_the_same_whether_hidden_samples_are_skipped_or_not() {
        let scene = cornell_box();
        let (_dir, baked) = three_view_bake(&scene);
        let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
        // Frames whose pixels are narrower than the bases' and wider,
        // from points along the walk.
        for (at, size, t, time_interp, supersample) in [
            (0.5, 64, 0.0, TimeInterp::Motion, 1),
            (0.5, 64, 0.5, TimeInterp::Motion, 2),
            (0.5, 64, 0.5, TimeInterp::Linear, 1),
            (0.1, 160, 0.0, TimeInterp::Motion, 1),
            (0.9, 160, 0.7, TimeInterp::Motion, 1),
        ] {
            let camera = scene
                .path("walk")
                .unwrap()
                .at(at)
                .perspective(size, size)
                .unwrap();
            let opts = Options {
                blend: Blend::Nearest,
                bases: 3,
                time_interp,
                supersample,
                ..Options::default()
            };
            let mut frame = |skip: bool| {
                synth.cull = skip;
                synth.frame(&camera, t, &opts).unwrap()
            };
            let (skipped, with) = frame(true);
            let (kept, without) = frame(false);
            let case = format!("{size}² at {at}, t = {t}, {time_interp}, {supersample}²");
            assert!(with.hidden > 0, "{case}: nothing was skipped");
            assert_eq!(without.hidden, 0, "{case}");
            let bits = |i: &RangeImage| -> Vec<u32> {
                i.radiance
                    .iter()
                    .flat_map(|c| c.to_array())
                    .chain(i.distance.iter().copied())
                    .map(f32::to_bits)
                    .chain(i.object_id.iter().copied())
                    .collect()
            };
            assert!(bits(&skipped) == bits(&kept), "{case}: frames differ");
        }
    }

    /// The holes a frame reports are counted as projection leaves them and
    /// as the fills take them, not looked for again: they must be the
    /// pixels its z-buffer leaves empty, with and without fills, whether
    /// or not there were holes to fill.
    #[test]
    fn holes_reported_are_the_empty_pixels_left() {
        let scene = cornell_box();
        let (_dir, baked) = three_view_bake(&scene);
        let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
        let camera = scene
            .path("walk")
            .unwrap()
            .at(0.9)
            .perspective(96, 80)
            .unwrap();
        let (mut some_holes, mut some_filled, mut none) = (false, false, false);
        for fill in [Fill::None, Fill::Foreground, Fill::Background, Fill::Both] {
            for time_interp in [TimeInterp::Motion, TimeInterp::Linear] {
                for (bases, fill_reach) in [(1, 2), (1, Options::default().fill_reach), (3, 2)] {
                    let opts = Options {
                        bases,
                        fill,
                        fill_reach,
                        time_interp,
                        supersample: 1,
                        ..Options::default()
                    };
                    let (_, stats) = synth.frame(&camera, 0.3, &opts).unwrap();
                    let empty = synth.buffers[0].iter().filter(|a| a.is_empty()).count();
                    let case =
                        format!("{fill:?}, {time_interp}, {bases} view(s), reach {fill_reach}");
                    assert_eq!(stats.holes, empty, "{case}");
                    some_holes |= stats.holes > 0;
                    some_filled |= stats.holes > 0 && stats.filled > 0;
                    none |= stats.holes == 0;
                }
            }
        }
        assert!(
            some_holes && some_filled && none,
            "{some_holes} {some_filled} {none}"
        );
    }

    /// A frame written into a recycled one's planes is the frame made
    /// afresh, wherever the recycled one had pixels and this one holes.
    #[test]
    fn recycled_frames_are_those_made_afresh() {
        let scene = cornell_box();
        let (_dir, baked) = three_view_bake(&scene);
        let walk = scene.path("walk").unwrap();
        let camera = |at: f32| walk.at(at).perspective(96, 80).unwrap();
        let bits = |i: &RangeImage| -> Vec<u32> {
            i.radiance
                .iter()
                .chain(&i.normal)
                .flat_map(|c| c.to_array())
                .chain(i.distance.iter().copied())
                .map(f32::to_bits)
                .chain(i.object_id.iter().copied())
                .chain(i.primitive_id.iter().copied())
                .collect()
        };
        for supersample in [1, 2] {
            // Holes where the recycled frame had none (splats, so that
            // subpixels are made).
            let (full, holey) = (
                Options {
                    supersample,
                    ..Options::default()
                },
                Options {
                    bases: 1,
                    fill: Fill::Foreground,
                    supersample,
                    ..Options::default()
                },
            );
            let mut fresh = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
            let (want, stats) = fresh.frame(&camera(0.9), 0.4, &holey).unwrap();
            assert!(stats.holes > 0, "{supersample}²: no holes");
            let mut synth = Synthesizer::new(&scene, &baked, DEFAULT_BUDGET);
            let (before, _) = synth.frame(&camera(0.1), 0.0, &full).unwrap();
            synth.recycle(before);
            let (got, _) = synth.frame(&camera(0.9), 0.4, &holey).unwrap();
            assert!(bits(&got) == bits(&want), "{supersample}²: frames differ");
            assert_eq!(got.meta.scene, want.meta.scene);
            assert_eq!(got.meta.camera, want.meta.camera);
        }
    }
}
