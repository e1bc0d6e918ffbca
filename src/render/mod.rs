//! Rendering: the reference path tracer (and later id-images and base-image
//! shading), all through the `accel::RayEngine` interface.
//!
//! The path tracer is unbiased: its images converge to the same values as
//! Mitsuba 3's `path` integrator on the exported scene (see
//! `docs/validation.md`). Work is split into tiles handed out by rayon; each
//! pixel sample draws from its own random stream, so an image depends only on
//! the seed, never on the number of threads.

use std::time::Instant;

use anyhow::{ensure, Result};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::accel::RayEngine;
use crate::camera::Camera;
use crate::image::{RangeImage, RangeMeta, NO_HIT};
use crate::progress::{ProgressBar, ProgressStyle};
use crate::ray::Ray;
use crate::scene::Scene;

mod hit;
mod integrator;
mod lights;
pub mod multipass;
pub mod noise;
pub mod surface;

use crate::rng::Pcg32;
use integrator::Integrator;
use lights::Lights;
use noise::{NoiseReport, NoiseTarget};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RenderSettings {
    /// Samples per pixel.
    pub spp: u32,
    /// Longest path in segments, counted as Mitsuba's `max_depth`
    /// (1: emitters seen directly, 2: direct lighting); `None`: unlimited,
    /// paths end by Russian roulette only.
    pub max_depth: Option<u32>,
    pub seed: u64,
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderStats {
    pub seconds: f64,
    /// Pixel samples taken.
    pub samples: u64,
    /// Every ray traced, shadow rays included.
    pub rays: u64,
}

const TILE: u32 = 16;
/// Tiles shaded between merges into the image: bounds the memory of
/// results waiting to be merged, whatever the image's size.
const TILES_PER_MERGE: usize = 1024;

/// One tile's new samples: for each pixel of the tile that took samples
/// this round, its index and the sums and luminance moments of its new
/// samples (see [`Shade`]).
struct TileResult {
    pixels: Vec<Shaded>,
    rays: u64,
}

/// One pixel's new samples: the sums and moments of those it counts, how
/// many it drew, and the sums of all of them.
struct Shaded {
    i: usize,
    sum: [DVec3; 3],
    batch: noise::Batch,
    drew: u32,
    all: [DVec3; 3],
}

/// Each pixel's samples so far, and what the round wants of it.
struct Counts<'a> {
    moments: &'a [noise::Moments],
    wanted: &'a [u32],
    drawn: &'a [u32],
    most: u32,
    /// Each pixel's centre object, where only samples that meet it count.
    own: Option<&'a [u32]>,
}

/// How a render sampled its pixels: every pixel's sample count and
/// estimated relative error (see [`noise`]), and what they come to.
#[derive(Clone, Debug, PartialEq)]
pub struct Sampled {
    /// Samples each pixel drew (a base pixel's include those it left out
    /// for meeting another object than its centre's).
    pub samples: Vec<u32>,
    pub error: Vec<f32>,
    /// The luminance below which errors are measured against it.
    pub floor: f64,
    pub report: NoiseReport,
}

/// Path traces `camera`'s view of `scene` at `time`. `engine` must already
/// hold the scene posed at `time`.
///
/// Besides the mean radiance, each pixel records the first hit of its centre
/// ray: distance, object and primitive id, and the normal turned towards the
/// camera.
pub fn render(
    scene: &Scene,
    engine: &dyn RayEngine,
    camera: &Camera,
    time: f32,
    settings: &RenderSettings,
) -> Result<(RangeImage, RenderStats)> {
    ensure!(settings.spp > 0, "render: spp must be at least 1");
    ensure!(
        scene.objects.len() < u32::MAX as usize,
        "render: too many objects"
    );
    let start = Instant::now();
    let integrator = Integrator {
        scene,
        engine,
        lights: Lights::new(scene, time),
        poses: scene.at(time),
        max_depth: settings.max_depth.unwrap_or(u32::MAX),
    };
    let meta = RangeMeta {
        camera: *camera,
        time,
        scene: format!(
            "{} t={time} path tracer ({}) spp={} max_depth={} seed={}",
            scene.source.display(),
            engine.name(),
            settings.spp,
            settings
                .max_depth
                .map_or("unlimited".to_string(), |d| d.to_string()),
            settings.seed
        ),
    };
    let mut image = RangeImage::empty(meta);
    let mut rays = first_hits(engine, camera, &mut image);
    let shade = |ray, _, rng: &mut Pcg32, rays: &mut u64| {
        (
            [integrator.radiance(ray, rng, rays), Vec3::ZERO, Vec3::ZERO],
            NO_HIT,
        )
    };
    let (traced, _, sampling) = shade_tiles(
        camera,
        settings,
        None,
        Coverage::Pixel,
        &mut image,
        &shade,
        Progress::Tiles,
    );
    rays += traced;
    let stats = RenderStats {
        seconds: start.elapsed().as_secs_f64(),
        samples: sampling.samples.iter().map(|&n| n as u64).sum(),
        rays,
    };
    Ok((image, stats))
}

/// The radiance a ray that leaves the scene at `t` along a unit direction
/// carries, as the renderers see it: the sun's disk where the ray points
/// into it, else nothing (a scene has no other sky).
pub fn sky(scene: &Scene, t: f32) -> impl Fn(Vec3) -> Vec3 + Sync {
    let lights = Lights::new(scene, t);
    move |dir| lights.sun_along(dir).map_or(Vec3::ZERO, |(le, _)| le)
}

/// Estimates one radiance sample along a camera ray, given the sample's
/// index within its pixel (for stratification); the last argument counts
/// the rays traced. Returns the whole radiance, the part of it that is
/// diffuse indirect light at the surfaces seen, and the part that is direct
/// light reflected by the diffuse lobe of the surface seen first (both zero
/// where a renderer does not tell them apart).
/// A sample's radiance (with the parts a multipass render keeps apart) and
/// the object its camera ray met first (`NO_HIT` for none).
type Shade<'a> = dyn Fn(Ray, u32, &mut Pcg32, &mut u64) -> ([Vec3; 3], u32) + Sync + 'a;

/// What a pixel's value averages: everything its samples see (a render's
/// antialiased pixel), or only the samples that meet the surface its centre
/// ray meets. A base image is of the second kind: its pixels are samples of
/// surfaces that synthesis moves one object at a time, and the share of a
/// neighbouring object's light in an edge pixel would move with the wrong
/// object (and, where a frame sees the surface larger than the base did,
/// spread over it). The frame's own footprints make its edges' mixture.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Coverage {
    Pixel,
    CentreObject,
}

/// Where a render reports its progress: its own bar over tiles, or a bar
/// owned by a larger job that counts pixels.
#[derive(Clone, Copy)]
pub enum Progress<'a> {
    Tiles,
    Pixels(&'a ProgressBar),
}

/// Shades `camera`'s view in tiles handed out by rayon, with progress,
/// writing mean radiances into `image`: every pixel takes `settings.spp`
/// samples, then, with a noise `target`, the pixels above it take more in
/// rounds (see [`noise`]). Returns the number of rays traced, the mean
/// parts of each pixel (see [`Shade`]) and how the pixels were sampled.
/// Which samples a round takes follows from the samples before it alone,
/// and those from (seed, pixel, sample index): never from the threads.
fn shade_tiles(
    camera: &Camera,
    settings: &RenderSettings,
    target: Option<&NoiseTarget>,
    coverage: Coverage,
    image: &mut RangeImage,
    shade: &Shade,
    progress: Progress,
) -> (u64, Vec<[Vec3; 2]>, Sampled) {
    let (w, h) = (camera.width, camera.height);
    let tiles: Vec<(u32, u32)> = (0..h.div_ceil(TILE))
        .flat_map(|ty| (0..w.div_ceil(TILE)).map(move |tx| (tx * TILE, ty * TILE)))
        .collect();
    let own = match progress {
        Progress::Tiles => Some(
            ProgressBar::new(tiles.len() as u64).with_style(
                ProgressStyle::with_template("{bar:40} {pos}/{len} tiles, {elapsed} ({eta} left)")
                    .expect("progress template is valid"),
            ),
        ),
        Progress::Pixels(_) => None,
    };
    let mut rays = 0;
    let mut parts = vec![[Vec3::ZERO; 2]; image.len()];
    let mut moments = vec![noise::Moments::default(); image.len()];
    // The count each pixel is to reach in the round about to run, and the
    // samples it has drawn (more than it counts where samples off its
    // centre's object are left out); no pixel draws more than `most`.
    let mut wanted = vec![settings.spp; image.len()];
    let mut drawn = vec![0u32; image.len()];
    let most = target.map_or(settings.spp, |t| t.max_spp.max(settings.spp));
    let centre_objects = (coverage == Coverage::CentreObject).then(|| image.object_id.clone());
    let mut floor = None;
    for round in 0.. {
        let active: Vec<(u32, u32)> = tiles
            .iter()
            .copied()
            .filter(|&(x0, y0)| {
                (y0..(y0 + TILE).min(h)).any(|y| {
                    (x0..(x0 + TILE).min(w)).any(|x| {
                        let i = (y * w + x) as usize;
                        wanted[i] > moments[i].n && drawn[i] < most
                    })
                })
            })
            .collect();
        if active.is_empty() {
            break;
        }
        if round > 0 {
            // Later rounds lengthen the bar by what they add.
            match (&own, progress) {
                (Some(bar), _) => bar.inc_length(active.len() as u64),
                (None, Progress::Pixels(bar)) => bar.inc_length(
                    (0..image.len())
                        .filter(|&i| wanted[i] > moments[i].n && drawn[i] < most)
                        .count() as u64,
                ),
                (None, Progress::Tiles) => {}
            }
        }
        for chunk in active.chunks(TILES_PER_MERGE) {
            let results: Vec<TileResult> = chunk
                .par_iter()
                .map(|&(x0, y0)| {
                    let counts = Counts {
                        moments: &moments,
                        wanted: &wanted,
                        drawn: &drawn,
                        most,
                        own: centre_objects.as_deref(),
                    };
                    let r = render_tile(shade, camera, settings, (x0, y0), &counts);
                    match (&own, progress) {
                        (Some(bar), _) => bar.inc(1),
                        (None, Progress::Pixels(bar)) => bar.inc(r.pixels.len() as u64),
                        (None, Progress::Tiles) => {}
                    }
                    r
                })
                .collect();
            for t in results {
                rays += t.rays;
                for Shaded {
                    i,
                    sum,
                    batch,
                    drew,
                    all,
                } in t.pixels
                {
                    drawn[i] += drew;
                    if moments[i].n + batch.n == 0 {
                        // No sample met the centre's object (a sliver
                        // narrower than the samples' spacing): the pixel
                        // keeps what its samples saw.
                        let n = drew.max(1) as f64;
                        image.radiance[i] = (all[0] / n).as_vec3();
                        parts[i] = [(all[1] / n).as_vec3(), (all[2] / n).as_vec3()];
                        continue;
                    }
                    let had = moments[i].n as f64;
                    let total = had + batch.n as f64;
                    let mean =
                        |old: Vec3, sum: DVec3| ((old.as_dvec3() * had + sum) / total).as_vec3();
                    image.radiance[i] = mean(image.radiance[i], sum[0]);
                    parts[i] = [mean(parts[i][0], sum[1]), mean(parts[i][1], sum[2])];
                    moments[i] = moments[i].merge(&batch);
                }
            }
        }
        let floor = *floor.get_or_insert_with(|| noise::floor(&moments, &image.object_id));
        let Some(target) = target else { break };
        let errors = noise::relative_errors(w, &moments, floor);
        for (i, (m, e)) in moments.iter().zip(&errors).enumerate() {
            if let Some(next) = noise::next_count(m.n, *e, target) {
                wanted[i] = next;
            }
        }
    }
    if let Some(bar) = own {
        bar.finish_and_clear();
    }
    let floor = floor.unwrap_or(0.0);
    let error = noise::relative_errors(w, &moments, floor);
    // What each pixel cost: a base pixel draws samples it leaves out.
    let report = NoiseReport::new(&image.object_id, &drawn, &error, target);
    let sampled = Sampled {
        samples: drawn,
        error,
        floor,
        report,
    };
    (rays, parts, sampled)
}

/// Where in its pixel each sample looks: the first `n²` samples
/// (`n = ⌊√spp⌋`) fall one in each cell of an `n × n` grid, which takes most
/// of the noise out of pixels an edge crosses (a light's outline dominates
/// the error of a Cornell box at low sample counts). Cells are dealt out in
/// a random order per pixel so that they are independent of the sample
/// index, which other dimensions (light samples) stratify on.
struct PixelStrata {
    n: u32,
    cells: Vec<u32>,
}

impl PixelStrata {
    /// For samples past the grid, which take their numbers as they come.
    const NONE: PixelStrata = PixelStrata {
        n: 0,
        cells: Vec::new(),
    };

    fn new(spp: u32, seed: u64, pixel: u64) -> Self {
        let n = spp.isqrt();
        let mut cells: Vec<u32> = (0..n * n).collect();
        let mut rng = Pcg32::for_sample(seed ^ 0x5eed_0f57_7a7a, pixel, u64::MAX);
        for i in (1..cells.len()).rev() {
            let j = ((rng.next_u32() as u64 * (i as u64 + 1)) >> 32) as usize;
            cells.swap(i, j);
        }
        Self { n, cells }
    }

    /// Offset within the pixel of sample `s` from two uniform numbers.
    fn offset(&self, s: u32, u: f32, v: f32) -> (f32, f32) {
        match self.cells.get(s as usize) {
            Some(&c) => {
                let inv = 1.0 / self.n as f32;
                (
                    (((c % self.n) as f32 + u) * inv).min(1.0 - f32::EPSILON),
                    (((c / self.n) as f32 + v) * inv).min(1.0 - f32::EPSILON),
                )
            }
            None => (u, v),
        }
    }
}

/// Takes the samples from each pixel's count so far (`moments`) up to
/// `wanted` in the tile whose corner is `(x0, y0)`.
fn render_tile(
    shade: &Shade,
    camera: &Camera,
    settings: &RenderSettings,
    (x0, y0): (u32, u32),
    counts: &Counts,
) -> TileResult {
    let x1 = (x0 + TILE).min(camera.width);
    let y1 = (y0 + TILE).min(camera.height);
    let mut pixels = Vec::new();
    let mut rays = 0;
    let grid = settings.spp.isqrt().pow(2);
    for y in y0..y1 {
        for x in x0..x1 {
            let i = (y * camera.width + x) as usize;
            let needed = counts.wanted[i].saturating_sub(counts.moments[i].n);
            let from = counts.drawn[i];
            let to = (from + needed).min(counts.most.max(from));
            if needed == 0 || from >= to {
                continue;
            }
            let own = counts.own.map(|o| o[i]);
            // Numbered in the whole projection, so that a pixel of a
            // window (a partial base) draws the samples it would uncropped.
            let pixel = camera.pixel_index(x, y);
            let strata = if from < grid {
                PixelStrata::new(settings.spp, settings.seed, pixel)
            } else {
                PixelStrata::NONE
            };
            let mut sum = [DVec3::ZERO; 3];
            let mut all = [DVec3::ZERO; 3];
            let mut batch = noise::Batch::default();
            for s in from..to {
                let mut rng = Pcg32::for_sample(settings.seed, pixel, s as u64);
                let (dx, dy) = strata.offset(s, rng.next_f32(), rng.next_f32());
                let Some(ray) = camera.pixel_ray(x, y, dx, dy) else {
                    batch.push(0.0);
                    continue;
                };
                let (l, object) = shade(ray, s, &mut rng, &mut rays);
                debug_assert!(
                    l[0].is_finite(),
                    "pixel ({x}, {y}) sample {s}: radiance {}",
                    l[0]
                );
                let finite = l.iter().all(|c| c.is_finite());
                if finite {
                    for (all, c) in all.iter_mut().zip(l) {
                        *all += c.as_dvec3();
                    }
                }
                if own.is_some_and(|o| o != object) {
                    continue;
                }
                if finite {
                    for (sum, c) in sum.iter_mut().zip(l) {
                        *sum += c.as_dvec3();
                    }
                    batch.push(noise::luminance(l[0]));
                } else {
                    batch.push(0.0);
                }
            }
            pixels.push(Shaded {
                i,
                sum,
                batch,
                drew: to - from,
                all,
            });
        }
    }
    TileResult { pixels, rays }
}

/// Fills distance, ids and normals from each pixel's centre ray; returns the
/// number of rays traced.
fn first_hits(engine: &dyn RayEngine, camera: &Camera, image: &mut RangeImage) -> u64 {
    let w = camera.width as usize;
    let traced: Vec<u64> = image
        .distance
        .par_chunks_mut(w)
        .zip(image.object_id.par_chunks_mut(w))
        .zip(image.primitive_id.par_chunks_mut(w))
        .zip(image.normal.par_chunks_mut(w))
        .enumerate()
        .map(|(y, (((dist, obj), prim), normal))| {
            let mut rays = 0;
            for x in 0..w {
                let Some(r) = camera.ray(x as f32 + 0.5, y as f32 + 0.5) else {
                    continue;
                };
                rays += 1;
                if let Some(h) = engine.intersect(&r) {
                    dist[x] = h.t * r.dir.length();
                    obj[x] = h.object;
                    prim[x] = h.primitive;
                    normal[x] = if h.normal.dot(r.dir) > 0.0 {
                        -h.normal
                    } else {
                        h.normal
                    };
                }
            }
            rays
        })
        .collect();
    traced.iter().sum()
}

#[cfg(test)]
mod tests {
    use super::PixelStrata;

    #[test]
    fn pixel_strata_put_one_sample_in_each_cell() {
        for spp in [1, 4, 16, 17, 64] {
            let strata = PixelStrata::new(spp, 3, 77);
            let n = spp.isqrt();
            let mut seen = vec![0; (n * n) as usize];
            for s in 0..n * n {
                let (x, y) = strata.offset(s, 0.5, 0.999_999);
                assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
                let cell = (y * n as f32) as u32 * n + (x * n as f32) as u32;
                seen[cell as usize] += 1;
            }
            assert!(seen.iter().all(|&c| c == 1), "spp {spp}: {seen:?}");
            // Samples beyond the grid take their numbers as they come.
            assert_eq!(strata.offset(n * n, 0.25, 0.75), (0.25, 0.75));
        }
        // The order of cells differs between pixels.
        let a = PixelStrata::new(64, 3, 1).cells;
        let b = PixelStrata::new(64, 3, 2).cells;
        assert_ne!(a, b);
    }
}
