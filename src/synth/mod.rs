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
use crate::image::{RangeImage, RangeMeta};
use crate::scene::Scene;

pub mod base;
mod cells;
mod fill;
mod indirect;
mod lights;
mod options;
mod pixels;
mod reshade;
pub mod walk;
mod warp;

pub use base::{Base, BaseCache, BYTES_PER_PIXEL};
use indirect::Records;
pub use options::{
    Blend, Fill, Filter, Options, TimeInterp, TimePlan, MAX_BASES, MAX_LIGHT_RAYS,
    MAX_RESHADE_SAMPLES, MAX_SUBPIXELS, MAX_SUPERSAMPLE,
};
use pixels::{blank, blend_linear, downsample, surface, write_pixels};
use warp::{Accum, Pass, Target, Twin, WarpSettings};

/// What making one frame took and found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Wall time, base loading included.
    pub seconds: f64,
    /// Of which reading and preparing bases.
    pub load_seconds: f64,
    /// Manifest indices of the base images used.
    pub images: Vec<usize>,
    /// How the frame's time was brought from theirs.
    pub plan: TimePlan,
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

/// What a frame projects and how its time is brought from theirs,
/// chosen once for all its subpixels.
struct Chosen {
    /// Manifest image, its weight in time, and whether it is the later of
    /// its view's two times.
    wanted: Vec<(usize, f32, bool)>,
    plan: TimePlan,
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
        opts.validate((camera.width, camera.height), &field)?;
        self.scene.check_time(t)?;
        let chosen = self.choose(camera.position, t, opts)?;
        // Without splats a sample lands on one subpixel: subpixels would
        // only thin the samples out, and a background fill would give most
        // of them the farther surface beside them.
        let k = opts.subpixels_per_side();
        if k == 1 {
            let (image, stats) = self.subpixels(camera, 1, t, opts, &chosen, true)?;
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
        let reshade = chosen.plan.reshade;
        let (fine_image, mut stats) =
            self.subpixels(&fine_camera, k, t, &fine, &chosen, reshade)?;
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

    /// The base images a frame at `position` and `t` projects (nearest
    /// view first, each view's nearer time first) and the plan its time
    /// follows.
    fn choose(&self, position: Vec3, t: f32, opts: &Options) -> Result<Chosen> {
        let mut wanted: Vec<(usize, f32, bool)> = Vec::new();
        for &v in &self.nearest_views(position, opts.bases) {
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
        let images = &self.bake.manifest.images;
        let times: Vec<f32> = wanted
            .iter()
            .map(|w| self.bake.manifest.plan.views[images[w.0].view].times[images[w.0].time_index])
            .collect();
        let plan = TimePlan::new(opts.time_interp, t, &times, !self.scene.is_static());
        Ok(Chosen { wanted, plan })
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
        chosen: &Chosen,
        image: bool,
    ) -> Result<(Option<RangeImage>, FrameStats)> {
        let start = Instant::now();
        let load_before = self.cache.load_seconds;
        let Chosen { wanted, plan } = chosen;
        let plan = *plan;
        let keep: Vec<usize> = wanted.iter().map(|w| w.0).collect();
        let mut bases: Vec<Arc<Base>> = Vec::with_capacity(wanted.len());
        for &(k, _, _) in wanted {
            bases.push(self.cache.get(self.bake, self.scene, k, &keep)?);
        }
        let target = Target::new(*camera);
        let background = matches!(opts.fill, Fill::Background | Fill::Both);
        let settings = WarpSettings {
            tolerance: opts.tolerance,
            splat: matches!(opts.fill, Fill::Foreground | Fill::Both),
            filter: opts.filter,
            blend: opts.blend,
            alpha: plan.alpha,
            sky: !background,
            cull: self.cull,
        };
        let poses_t = self.scene.at(t);
        let moves_of = |base: &Base| -> Vec<Option<Affine3A>> {
            if !plan.moved {
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
            plan,
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
        let pixels: Vec<Accum> = if plan.apart {
            // pinterp per time, then pcomb: two frames blended per pixel.
            alloc::resize(&mut second, n, Accum::default(), z_buffer("second "))?;
            let passes = |later: bool| -> Vec<Pass> {
                bases
                    .iter()
                    .zip(wanted)
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
        if plan.reshade {
            let scene = self.scene;
            let mut times: Vec<f32> = bases.iter().map(|b| b.time).collect();
            times.sort_by(f32::total_cmp);
            times.dedup();
            let (w, cam) = (camera.width as usize, camera.position);
            let plane = |what: &str| reshade::light_plane(pixels.len(), w, what);
            let mut now = plane("the frame's time")?;
            let mut then = Vec::with_capacity(times.len());
            for &time in &times {
                then.push(plane(&format!("base time {time}"))?);
            }
            // The frame's time first, then every base time.
            let all_times: Vec<f32> = std::iter::once(t).chain(times.iter().copied()).collect();
            // Without it every change found would be nought: the planes
            // stay dark and the bases' light is kept as it is.
            if plan.direct {
                stats.reshaded = self.light_at_times(
                    (&pixels, w, cam, k),
                    t,
                    &all_times,
                    opts,
                    &mut now,
                    &mut then,
                )?;
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

    /// The diffuse direct light of `pixels` (a frame of width `w` seen
    /// from `cam`, `k` × `k` subpixels a pixel, at `t`) at the frame's time
    /// into `now` and at every base time into `then` (`times`: the frame's
    /// first). Every pixel first takes a few samples at every time, which
    /// find where the light changed; there the frame's and the base times'
    /// light are drawn again with all of `reshade_samples`. Returns how
    /// many pixels were.
    fn light_at_times(
        &mut self,
        (pixels, w, cam, k): (&[Accum], usize, Vec3, u32),
        t: f32,
        times: &[f32],
        opts: &Options,
        now: &mut [Vec3],
        then: &mut [Vec<Vec3>],
    ) -> Result<usize> {
        let scene = self.scene;
        let find = reshade::FIND_SAMPLES.div_ceil(k * k);
        let (mut samples, mut only) = (find, None::<Vec<bool>>);
        let mut reshaded = 0;
        loop {
            for (i, &time) in times.iter().enumerate() {
                let engine = &*self.engine_at(time)?;
                let out = if i == 0 { &mut *now } else { &mut then[i - 1] };
                reshade::direct_at(
                    scene,
                    engine,
                    t,
                    time,
                    pixels,
                    w,
                    cam,
                    samples,
                    opts.seed,
                    only.as_deref(),
                    out,
                )?;
            }
            if only.is_some() || opts.reshade_samples <= find {
                return Ok(reshaded);
            }
            let changed = reshade::changed(now, then, w, k as usize);
            reshaded = changed.iter().filter(|&&c| c).count();
            (samples, only) = (opts.reshade_samples, Some(changed));
        }
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

/// The warning for a camera outside the view space, if it is.
pub fn view_space_warning(scene: &Scene, what: &str, position: Vec3) -> Option<String> {
    let space = scene.view_space.as_ref()?;
    (!space.contains(position)).then(|| {
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
    use crate::scene::ViewSpace;

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
            quality: crate::quality::Quality::new(0.6).unwrap(),
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
