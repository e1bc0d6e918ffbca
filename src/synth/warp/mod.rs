//! Forward projection of base pixels into a frame with a z-buffer, as
//! Radiance's `pinterp` does it: a sample replaces what a pixel holds when
//! it is nearer by more than the relative tolerance, joins it when within
//! the tolerance (weighted by how close the base ray is to the frame's ray)
//! or, with `Blend::Nearest`, loses to the sample already there.
//!
//! The frame is cut into bands of rows, one rayon task each; every task
//! goes through the tiles of every pass whose projected bounds reach its
//! rows, in pass order, so the result does not depend on the thread count.
//! A tile's pixels are projected once a frame ([`prepare_tile`]), by the
//! first band that needs them when several do, and deposited by each band
//! into its own rows ([`deposit_splats`]).

use std::sync::OnceLock;

use glam::{Affine3A, Vec2, Vec3};
use rayon::prelude::*;

use super::base::{Base, SKY, TILE};
use super::cells::Cells;
pub use super::options::{Blend, Filter};

mod cull;
mod deposit;
mod project;
mod target;

use cull::hidden;
use deposit::{deposit_splats, Band};
use project::{prepare_tile, Splat};
use target::Reach;
pub use target::Target;

/// Depth of a pixel that sees nothing: farther than any surface.
pub const SKY_Z: f32 = 1e30;
/// What a frame pixel has gathered, once every pass is projected.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Accum {
    /// Distance from the frame's camera; 0 where nothing arrived.
    pub z: f32,
    /// Sum of the samples' weights and of their weighted values.
    pub w: f32,
    pub radiance: Vec3,
    /// Weighted sum of the samples' time fractions (linear blending) or
    /// base times (re-shading: which times it finds the pixel's light
    /// blended from); 0 where neither asks for it.
    pub alpha: f32,
    /// The heaviest sample's world point (at the frame's time), object and
    /// primitive: the surface the pixel shows.
    pub point: Vec3,
    pub object: u32,
    pub primitive: u32,
    /// How far (in pixels) background fill carried the value; 0 for a
    /// projected sample.
    pub reach: u16,
}

/// What a frame pixel holds while passes are projected into it: only what
/// the depth test and blending read and write, half a cache line, so that
/// a band of the frame stays in the core's cache (with the whole `Accum`
/// most deposits missed it). The heaviest sample is named by its base
/// pixel and pass; its point and ids are looked up once the band is done.
#[derive(Clone, Copy, Debug, Default)]
#[repr(align(32))]
struct Hot {
    z: f32,
    w: f32,
    radiance: Vec3,
    /// The heaviest sample's weight and base pixel.
    best: f32,
    pixel: u32,
    /// In the lowest bit, whether a sample's footprint covers the pixel's
    /// centre: such a sample decides the pixel's surface, and samples whose
    /// footprints only overlap the pixel's edge join it only within the
    /// tolerance. Above it the heaviest sample's pass ([`PASS_BITS`]) and
    /// its object's number (the rest of the bits of it).
    tag: u32,
}

/// Bits of a [`Hot`]'s tag that name the pass.
const PASS_BITS: u32 = 12;
/// Most passes one frame may project.
const MAX_PASSES: usize = 1 << PASS_BITS;
const _: () = assert!(MAX_PASSES >= 2 * super::options::MAX_BASES);
const _: () = assert!(size_of::<Accum>() as u64 == super::options::SUBPIXEL_BYTES);

/// A sample's tag: its pass and (as many low bits of it as fit) its object.
fn tag(pass: u32, object: u32) -> u32 {
    debug_assert!((pass as usize) < MAX_PASSES);
    (object << (PASS_BITS + 1)) | (pass << 1)
}

impl Hot {
    fn covered(&self) -> bool {
        self.tag & 1 != 0
    }

    fn pass(&self) -> usize {
        ((self.tag >> 1) & (MAX_PASSES as u32 - 1)) as usize
    }

    /// Whether a sample tagged `tag` shows the object this pixel holds
    /// (objects whose numbers agree in the tag's bits count as one).
    fn same_object(&self, tag: u32) -> bool {
        (self.tag ^ tag) >> (PASS_BITS + 1) == 0
    }
}

impl Accum {
    pub fn is_empty(&self) -> bool {
        self.z == 0.0
    }
}

/// One base image projected at one weight.
pub struct Pass<'a> {
    pub base: &'a Base,
    /// Per object: the motion from the base's time to the frame's,
    /// `M(t) · M(t_i)⁻¹`, for objects that move (motion compensation).
    pub moves: Vec<Option<Affine3A>>,
    /// Weight of every sample of this pass (closeness in time).
    pub weight: f32,
    /// The time fraction this pass stands for (linear blending), or its
    /// base's time (motion compensation).
    pub alpha: f32,
    /// The same view's image at the other bracketing time, whose pixels on
    /// surfaces that do not move are the same world points: they are
    /// projected once, by the pass that carries them.
    pub twin: Option<Twin<'a>>,
}

/// How a pass shares the pixels it has in common with its twin.
#[derive(Clone, Copy)]
pub enum Twin<'a> {
    /// This pass projects the shared pixels with the twin's radiance
    /// blended in at the twin's weight in time (and its `alpha`).
    Carries {
        base: &'a Base,
        weight: f32,
        alpha: f32,
    },
    /// The twin's pass projects the shared pixels; this one the rest.
    CarriedBy(&'a Base),
}

impl Twin<'_> {
    fn base(&self) -> &Base {
        match self {
            Twin::Carries { base, .. } | Twin::CarriedBy(base) => base,
        }
    }
}

impl Pass<'_> {
    /// Whether pixel `k` shows the same unmoving point in this pass's base
    /// and in its twin's (both are images of one camera).
    #[inline(always)]
    fn shared(&self, k: usize) -> bool {
        let Some(twin) = &self.twin else {
            return false;
        };
        let (a, b) = (self.base, twin.base());
        let o = a.object[k];
        o == b.object[k]
            && a.primitive[k] == b.primitive[k]
            && if o == SKY {
                a.points[k] == b.points[k]
            } else {
                self.moves
                    .get(o as usize)
                    .and_then(Option::as_ref)
                    .is_none()
            }
    }

    /// Whether tile `t` shows no moving object in this pass's base nor in
    /// its twin's: then every pixel of it is shared (one camera's centre
    /// rays meet the same unmoving surfaces).
    fn tile_shared(&self, t: usize) -> bool {
        self.twin.as_ref().is_some_and(|twin| {
            self.base.tiles[t].moving.is_empty() && twin.base().tiles[t].moving.is_empty()
        })
    }
}

#[derive(Clone, Copy, Debug)]
pub struct WarpSettings {
    pub tolerance: f32,
    pub splat: bool,
    pub filter: Filter,
    pub blend: Blend,
    /// Whether pixels sum their samples' `alpha` (linear blending and
    /// re-shading read it).
    pub alpha: bool,
    /// Whether base pixels that see nothing are projected, as directions.
    /// Where the frame's holes are traced (a background fill), its own
    /// rays find its sky exactly; a base's sky pixel lands by its
    /// direction alone, wherever that falls, and in a gap between a
    /// surface's samples it claims a pixel of the surface (dark dots down
    /// a box's edge), while one that holds part of a surface (a window
    /// bar) carries that surface's light into the sky.
    pub sky: bool,
    /// Whether nearest-first blending leaves out the samples of later
    /// passes that cannot change a pixel: only a saving, frames are bit for
    /// bit the same without it.
    pub cull: bool,
}

impl WarpSettings {
    /// Whether later passes are left out where they cannot change a pixel.
    fn culls(&self) -> bool {
        self.blend == Blend::Nearest && self.cull
    }
}

/// A projected base pixel: what its neighbours' footprints and depth
/// tests read, small so that a tile's projections stay in the core's
/// fastest cache.
#[derive(Clone, Copy)]
struct Projected {
    px: Vec2,
    z: f32,
    /// [`SKY`] for a direction.
    object: u32,
    primitive: u32,
}

impl Projected {
    fn sky(&self) -> bool {
        self.object == SKY
    }
}

/// Projects every pass into `buffer` (`width * height`, row-major),
/// whatever it held before. Returns how many base pixels nearest-first
/// blending left out of a band because they could not change it (a pixel
/// of a tile counts once for each band it was left out of).
/// What [`warp`] counted: base pixels nearest-first blending left out
/// (once for every band they were left out of), and frame pixels no sample
/// reached, so that the fills need not look for holes where none are.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Warped {
    pub hidden: usize,
    pub holes: usize,
}

impl std::iter::Sum for Warped {
    fn sum<I: Iterator<Item = Warped>>(iter: I) -> Warped {
        iter.fold(Warped::default(), |a, b| Warped {
            hidden: a.hidden + b.hidden,
            holes: a.holes + b.holes,
        })
    }
}

pub fn warp(
    target: &Target,
    passes: &[Pass],
    settings: &WarpSettings,
    buffer: &mut [Accum],
) -> Warped {
    let (w, h) = (target.camera.width, target.camera.height);
    debug_assert_eq!(buffer.len(), (w * h) as usize);
    assert!(
        passes.len() <= MAX_PASSES,
        "at most {MAX_PASSES} passes a frame"
    );
    // Sixteen bands: with eight, one core waited on the other for a tenth
    // of the frame (a band is a unit of work, and they differ in cost).
    let band = (h / 16).max(16);
    let bands = h.div_ceil(band) as usize;
    // Every (pass, tile) that may reach the frame, in pass order.
    let lists: Vec<Vec<(u32, u32, Reach)>> = passes
        .par_iter()
        .enumerate()
        .map(|(i, pass)| {
            let base = pass.base;
            let mut list = Vec::new();
            for block in &base.blocks {
                let seen = block.moving
                    || block
                        .fixed
                        .is_some_and(|b| target.rows(&b, false).is_some())
                    || block.sky.is_some_and(|b| target.rows(&b, true).is_some());
                if !seen {
                    continue;
                }
                for t in base.tiles_of(block) {
                    let Some(reach) = target.tile_reach(&base.tiles[t], &pass.moves) else {
                        continue;
                    };
                    if matches!(pass.twin, Some(Twin::CarriedBy(_))) && pass.tile_shared(t) {
                        continue;
                    }
                    if reach.rows.1 > reach.rows.0 {
                        list.push((i as u32, t as u32, reach));
                    }
                }
            }
            list
        })
        .collect();
    // A tile reaching several bands is prepared once, by the first band
    // that needs it, into a slot the others read: projecting it again for
    // every band cost a third more than projecting it once.
    let items: Vec<(u32, u32, Reach)> = lists.into_iter().flatten().collect();
    let mut work: Vec<Vec<(usize, Option<usize>)>> = vec![Vec::new(); bands];
    let mut slots = 0;
    for (n, &(_, _, reach)) in items.iter().enumerate() {
        let (a, b) = reach.rows;
        let (first, last) = ((a / band) as usize, ((b - 1) / band) as usize);
        let slot = (last > first).then(|| {
            slots += 1;
            slots - 1
        });
        for band_items in &mut work[first..=last] {
            band_items.push((n, slot));
        }
    }
    let prepared: Vec<OnceLock<Vec<Splat>>> = (0..slots).map(|_| OnceLock::new()).collect();
    let cull = settings.culls();
    buffer
        .par_chunks_mut((band * w) as usize)
        .zip(work.par_iter())
        .enumerate()
        .map(|(k, (rows, band_items))| {
            let y0 = k as u32 * band;
            SCRATCH.with_borrow_mut(|scratch| {
                // Kept by the thread from band to band and frame to frame:
                // fresh pages for every band cost more than projecting it.
                let n = rows.len();
                let Scratch {
                    projected,
                    layers,
                    splats,
                    hot,
                    alpha,
                    cells,
                } = scratch;
                let mut summed = false;
                hot.clear();
                hot.resize(n, Hot::default());
                alpha.clear();
                alpha.resize(if settings.alpha { n } else { 0 }, 0.0);
                let mut band = Band {
                    y0,
                    width: w,
                    hot,
                    alpha,
                    hidden: 0,
                };
                for &(item, slot) in band_items {
                    let (i, t, reach) = items[item];
                    let pass = &passes[i as usize];
                    let (tile, base) = (&pass.base.tiles[t as usize], pass.base);
                    // The band as the first pass left it: later ones are
                    // mostly left out, and a cell settles many of their
                    // tests at once.
                    if cull && i > 0 && !summed {
                        let rows = band.hot.len() as u32 / w;
                        cells.build((w, h), (y0, rows), target.focal, |j| {
                            let p = &band.hot[j];
                            p.covered().then_some(p.z)
                        });
                        summed = true;
                    }
                    if cull
                        && hidden(
                            target,
                            (tile, &pass.moves),
                            (band.hot, summed.then_some(&*cells)),
                            y0,
                            &reach,
                            settings.tolerance,
                        )
                    {
                        let side = |at: u32, n: u32| ((at + TILE).min(n) - at) as usize;
                        band.hidden += side(tile.x0, base.width()) * side(tile.y0, base.height());
                        continue;
                    }
                    let mut prepare = |out: &mut Vec<Splat>| {
                        prepare_tile(target, pass, t as usize, settings, projected, layers, out)
                    };
                    let tile_splats: &[Splat] = match slot {
                        Some(slot) => prepared[slot].get_or_init(|| {
                            let mut out = Vec::with_capacity((TILE * TILE) as usize);
                            prepare(&mut out);
                            out
                        }),
                        None => {
                            prepare(splats);
                            splats
                        }
                    };
                    deposit_splats(target, (i, pass), tile_splats, settings, &mut band);
                }
                Warped {
                    hidden: band.hidden,
                    holes: resolve(passes, band.hot, band.alpha, rows),
                }
            })
        })
        .sum()
}

/// The band's pixels from what they gathered: the heaviest sample's point
/// and ids looked up in its pass. Overlap alone does not make a pixel
/// seen: where no footprint covers its centre (a disocclusion's edge), it
/// stays a hole for the fills rather than taking the foreground's edge.
/// Returns the number of holes.
fn resolve(passes: &[Pass], hot: &[Hot], alpha: &[f32], rows: &mut [Accum]) -> usize {
    let mut holes = 0;
    for (j, (a, h)) in rows.iter_mut().zip(hot).enumerate() {
        if h.z == 0.0 || !h.covered() {
            *a = Accum::default();
            holes += 1;
            continue;
        }
        let pass = &passes[h.pass()];
        let base = pass.base;
        let k = h.pixel as usize;
        let (p, object) = (base.points[k], base.object[k]);
        let point = match pass.moves.get(object as usize).and_then(Option::as_ref) {
            Some(m) => m.transform_point3(p),
            None => p,
        };
        *a = Accum {
            z: h.z,
            w: h.w,
            radiance: h.radiance,
            alpha: alpha.get(j).copied().unwrap_or(0.0),
            point,
            object,
            primitive: base.primitive[k],
            reach: 0,
        };
    }
    holes
}

/// What a thread reuses from tile to tile and band to band.
#[derive(Default)]
struct Scratch {
    /// The tile's pixels (and the row and column after it) projected.
    projected: Vec<Option<Projected>>,
    /// Radiance and the twin's radiance of the tile's pixels, as f32
    /// triples.
    layers: [Vec<f32>; 2],
    /// The samples of a tile that reaches one band.
    splats: Vec<Splat>,
    /// The band's pixels, and their sums of `alpha` where asked for.
    hot: Vec<Hot>,
    alpha: Vec<f32>,
    /// The band's cells, once its first pass is deposited.
    cells: Cells,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::default();
}
