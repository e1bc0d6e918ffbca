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
use half::{f16, slice::HalfFloatSliceExt};
use rayon::prelude::*;

use super::base::{Base, Bounds, Tile, SKY, TILE};
use super::cells::{Cells, Facing, CELL};
use crate::camera::{Camera, Projection};

/// Depth of a pixel that sees nothing: farther than any surface.
pub const SKY_Z: f32 = 1e30;
/// Largest weight of a sample, for rays that coincide (pinterp's cap).
const MAX_WEIGHT: f32 = 1000.0;
/// Longest side (in frame pixels) a splat may stretch to; beyond it a
/// sample covers one pixel.
const MAX_SPLAT: f32 = 64.0;
/// Smallest share of a pixel a footprint's overlap counts for.
const MIN_AREA: f32 = 1e-3;

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
pub const MAX_PASSES: usize = 1 << PASS_BITS;

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
pub enum Blend {
    /// The first base (nearest the frame's camera) wins among samples
    /// within the tolerance (pinterp `-q`).
    Nearest,
    /// Samples within the tolerance are averaged, weighted by 1/sin of the
    /// angle between the base's ray and the frame's (pinterp `-a`).
    Average,
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
pub enum Filter {
    /// A splat joins every pixel it overlaps, weighed by the overlap, and
    /// decides those whose centres it covers: a box filter of the base's
    /// pixels.
    Box,
    /// A splat reaches only the pixels whose centres it covers: a quarter
    /// to a third less time a frame, for an LRMS up to a tenth higher from
    /// bases as fine as the frame (less of their noise averaged away) and
    /// up to a third from coarser ones, at the same FLIP.
    Cover,
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

/// The frame's camera with what projecting into it needs precomputed.
pub struct Target {
    pub camera: Camera,
    /// Pixels per unit of `x/z` and `y/z` (pinhole frames).
    focal: Option<f32>,
}

impl Target {
    pub fn new(camera: Camera) -> Self {
        let focal = match camera.projection {
            Projection::Perspective { vfov_deg } => {
                Some(0.5 * camera.height as f32 / (vfov_deg.to_radians() * 0.5).tan())
            }
            _ => None,
        };
        Self { camera, focal }
    }

    fn local(&self, d: Vec3) -> Vec3 {
        let c = &self.camera;
        Vec3::new(d.dot(c.right), d.dot(c.up), d.dot(c.forward))
    }

    /// Pinhole pixel position of a camera-space vector, `None` behind.
    #[inline]
    fn pinhole(&self, f: f32, d: Vec3) -> Option<Vec2> {
        let l = self.local(d);
        if l.z <= 0.0 {
            return None;
        }
        let inv = f / l.z;
        Some(Vec2::new(
            0.5 * self.camera.width as f32 + l.x * inv,
            0.5 * self.camera.height as f32 - l.y * inv,
        ))
    }

    /// Continuous pixel position of a world point (not clipped to the
    /// image, so that splats can cross its edge) and its distance.
    #[inline]
    pub fn point(&self, p: Vec3) -> Option<(Vec2, f32)> {
        let d = p - self.camera.position;
        match self.focal {
            Some(f) => self.pinhole(f, d),
            None => self.camera.project(p),
        }
        .map(|px| (px, d.length()))
    }

    /// About how many frame pixels a base pixel's side spans, seen at
    /// distance `z` from the frame's camera: the base pixel's angle times
    /// its distance from the base's camera, over `z`, over the angle of a
    /// frame pixel (each at its image's centre).
    fn pixel_side(&self, base: &Base, point: Vec3, z: f32) -> f32 {
        let seen = pixel_angle(&base.camera) * point.distance(base.camera.position) / z;
        (seen / pixel_angle(&self.camera)).max(1e-3)
    }

    /// Pixel position of a direction (a point at infinity).
    #[inline]
    pub fn direction(&self, d: Vec3) -> Option<Vec2> {
        match self.focal {
            Some(f) => self.pinhole(f, d),
            None => {
                // Far enough that the position's rounding does not turn
                // the direction, near enough that its square stays finite.
                let far = 1e3 * (1.0 + self.camera.position.abs().max_element());
                self.camera.project(self.camera.position + d * far)
            }
        }
    }

    /// Rows a box of points may reach, or `None` where the frame cannot
    /// see it. Only pinhole frames are culled.
    fn rows(&self, b: &Bounds, directions: bool) -> Option<(u32, u32)> {
        self.reach(b, directions).map(|r| r.rows)
    }

    /// The part of the frame a box of points may reach and how near it
    /// comes, or `None` where the frame cannot see it. Only pinhole frames
    /// are culled and bounded; other frames are reached whole.
    fn reach(&self, b: &Bounds, directions: bool) -> Option<Reach> {
        let (w, h) = (self.camera.width, self.camera.height);
        let near = if directions {
            SKY_Z
        } else {
            let p = self.camera.position;
            (b.lo - p).max(p - b.hi).max(Vec3::ZERO).length()
        };
        let whole = Reach {
            rows: (0, h),
            cols: (0, w),
            near,
        };
        let Some(f) = self.focal else {
            return Some(whole);
        };
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        let mut behind = 0;
        // Corners outside each side of the frustum (with a pixel to spare):
        // a box with all eight outside one side is not seen.
        let (ax, ay) = ((0.5 * w as f32 + 2.0) / f, (0.5 * h as f32 + 2.0) / f);
        let mut outside = [0; 4];
        for c in b.corners() {
            let l = if directions {
                self.local(c)
            } else {
                self.local(c - self.camera.position)
            };
            outside[0] += (l.x > l.z * ax) as u32;
            outside[1] += (l.x < -l.z * ax) as u32;
            outside[2] += (l.y > l.z * ay) as u32;
            outside[3] += (l.y < -l.z * ay) as u32;
            if l.z <= 0.0 {
                behind += 1;
                continue;
            }
            let inv = f / l.z;
            let q = Vec2::new(l.x * inv, -l.y * inv);
            lo = lo.min(q);
            hi = hi.max(q);
        }
        if behind == 8 || outside.contains(&8) {
            return None;
        }
        if behind > 0 {
            return Some(whole);
        }
        let half = Vec2::new(w as f32, h as f32) * 0.5;
        let (lo, hi) = (lo + half - 1.0, hi + half + 1.0);
        if hi.x < 0.0 || hi.y < 0.0 || lo.x > w as f32 || lo.y > h as f32 {
            return None;
        }
        let span =
            |lo: f32, hi: f32, n: u32| (lo.max(0.0) as u32, (hi.ceil().max(0.0) as u32 + 1).min(n));
        Some(Reach {
            rows: span(lo.y, hi.y, h),
            cols: span(lo.x, hi.x, w),
            near,
        })
    }

    /// What a tile of a pass may reach (its points moved to the frame's
    /// time).
    fn tile_reach(&self, tile: &Tile, moves: &[Option<Affine3A>]) -> Option<Reach> {
        let mut range: Option<Reach> = None;
        let mut add = |r: Option<Reach>| {
            if let Some(r) = r {
                range = Some(range.map_or(r, |u| u.union(&r)));
            }
        };
        if let Some(b) = &tile.fixed {
            add(self.reach(b, false));
        }
        if let Some(b) = &tile.sky {
            add(self.reach(b, true));
        }
        for (o, b) in &tile.moving {
            match moves.get(*o as usize).and_then(Option::as_ref) {
                Some(m) => {
                    let mut moved = Bounds::EMPTY;
                    for c in b.corners() {
                        moved.grow(m.transform_point3(c));
                    }
                    add(self.reach(&moved, false));
                }
                None => add(self.reach(b, false)),
            }
        }
        range
    }
}

/// The frame pixels a box of points may reach (half-open rows and
/// columns) and its nearest distance from the frame's camera.
#[derive(Clone, Copy, Debug)]
struct Reach {
    rows: (u32, u32),
    cols: (u32, u32),
    near: f32,
}

impl Reach {
    fn union(&self, o: &Reach) -> Reach {
        Reach {
            rows: (self.rows.0.min(o.rows.0), self.rows.1.max(o.rows.1)),
            cols: (self.cols.0.min(o.cols.0), self.cols.1.max(o.cols.1)),
            near: self.near.min(o.near),
        }
    }
}

/// The angle a camera's centre pixel subtends (every pixel's, for the
/// equal-area sphere).
fn pixel_angle(c: &Camera) -> f32 {
    let (w, h) = c.full_size();
    match c.projection {
        Projection::Perspective { vfov_deg } => {
            2.0 * (vfov_deg.to_radians() * 0.5).tan() / h as f32
        }
        Projection::Fisheye => std::f32::consts::PI / w.min(h) as f32,
        Projection::Sphere => (4.0 * std::f32::consts::PI).sqrt() / h as f32,
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

/// Frame pixels around a tile's reach that its footprints may still
/// touch: a footprint reaches half its extent, about a base pixel's
/// projected size, past its sample.
const REACH_MARGIN: u32 = 2;

/// Share of a tile's depth kept back from its slabs' bound: a footprint
/// gives a pixel its sample's depth extrapolated linearly along the frame,
/// which departs from the plane's own depth there by terms of second order
/// in the distance it is carried. Half the tolerance, so that the samples
/// of a surface an earlier base holds stay within it.
///
/// Not a proof: a sample beside an edge whose neighbour across it agrees
/// in depth takes its gradient from both faces and may depart by more.
/// A sample left out for that has a surface within a few percent of the
/// depth its pixel holds. Slabs for each face of an edge changed frames
/// that way; these, one for all the fixed points and one for each moving
/// object, left the benchmark's frames bit for bit the same.
const SLAB_MARGIN: f32 = 0.01;

/// Whether samples of `tile` (its points moved by `moves`), which reaches
/// `reach`, cannot change the band's pixels `hot` (rows `y0..`) under
/// nearest-first blending: every pixel it may touch is covered by an
/// earlier sample, and none of its points is nearer than those by more
/// than the tolerance. Then a later base adds nothing there, and its tile
/// is not projected: where the nearest base sees the frame, the others
/// cost nothing.
///
/// A tile's depth at a pixel is at least its nearest point's distance;
/// also the least distance along the pixel's ray to the slabs of its
/// points (but no more than twice the nearest point's, the most a
/// footprint carries its sample's depth). Its sky is as far as can be.
fn hidden(
    target: &Target,
    (tile, moves): (&Tile, &[Option<Affine3A>]),
    (hot, cells): (&[Hot], Option<&Cells>),
    y0: u32,
    reach: &Reach,
    eps: f32,
) -> bool {
    let width = target.camera.width;
    let y1 = y0 + hot.len() as u32 / width;
    let (ya, yb) = (
        reach.rows.0.saturating_sub(REACH_MARGIN).max(y0),
        (reach.rows.1 + REACH_MARGIN).min(y1),
    );
    let (xa, xb) = (
        reach.cols.0.saturating_sub(REACH_MARGIN),
        (reach.cols.1 + REACH_MARGIN).min(width),
    );
    if ya >= yb || xa >= xb {
        return true;
    }
    let near = reach.near;
    let limit = near / (1.0 - eps);
    // A slab's distance along pixel (x, y)'s ray: with the ray
    // d = f·forward + u·right + v·up, it is (|g| − δ)·|d| / |n·d| where the
    // camera lies at signed distance g from the slab's middle on the side
    // the ray faces. Where the camera is within a slab, none bounds.
    let f = target.focal.unwrap_or(0.0);
    let c = &target.camera;
    let mut slabs = [Facing {
        gap: 0.0,
        normal: Vec3::ZERO,
    }; 4];
    let bounded = target.focal.is_some()
        && tile.slabs.len() <= slabs.len()
        && tile.slabs.iter().zip(&mut slabs).all(|((o, s), out)| {
            let s = match o.and_then(|o| moves.get(o as usize)?.as_ref()) {
                Some(m) => s.moved(m),
                None => *s,
            };
            let g = s.offset - s.normal.dot(c.position);
            let sign = g.signum();
            *out = Facing {
                gap: (g.abs() - s.half_width) * (1.0 - SLAB_MARGIN),
                normal: sign
                    * Vec3::new(
                        s.normal.dot(c.forward),
                        s.normal.dot(c.right),
                        s.normal.dot(c.up),
                    ),
            };
            out.gap > 0.0
        });
    let slabs = &slabs[..if bounded { tile.slabs.len() } else { 0 }];
    let (hw, hh) = (0.5 * width as f32, 0.5 * c.height as f32);
    let cap = 2.0 * near;
    // Whether rows `ya..yb`, columns `xa..xb` pass, pixel by pixel.
    let pixels = |(ya, yb): (u32, u32), (xa, xb): (u32, u32)| {
        (ya..yb).all(|y| {
            let row = ((y - y0) * width) as usize;
            let v = hh - (y as f32 + 0.5);
            hot[row + xa as usize..row + xb as usize]
                .iter()
                .zip(xa..xb)
                .all(|(p, x)| {
                    if !p.covered() {
                        return false;
                    }
                    if p.z <= limit {
                        return true;
                    }
                    // The depth to beat; past twice the nearest point's, no
                    // footprint's depth can be shown to reach it.
                    let beat = p.z * (1.0 - eps);
                    if slabs.is_empty() || beat > cap {
                        return false;
                    }
                    // Each slab's gap·|d| / (n·d) ≥ beat, squared to spare
                    // a root and a division.
                    let u = x as f32 + 0.5 - hw;
                    let length2 = f * f + u * u + v * v;
                    slabs.iter().all(|s| {
                        let facing = s.normal.dot(Vec3::new(f, u, v));
                        facing > 0.0 && s.gap * s.gap * length2 >= (beat * facing).powi(2)
                    })
                })
        })
    };
    let Some(cells) = cells else {
        return pixels((ya, yb), (xa, xb));
    };
    // Cell by cell, the pixels of those that cannot settle it one by one.
    (ya / CELL..=(yb - 1) / CELL).all(|cy| {
        let rows = ((cy * CELL).max(ya), ((cy + 1) * CELL).min(yb));
        (xa / CELL..=(xb - 1) / CELL).all(|cx| {
            cells.hide((cx, cy - y0 / CELL), (limit, cap), eps, slabs)
                || pixels(rows, ((cx * CELL).max(xa), ((cx + 1) * CELL).min(xb)))
        })
    })
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

/// A base pixel projected into the frame, with everything its deposits
/// need that does not depend on the band they land in.
#[derive(Clone, Copy)]
struct Splat {
    px: Vec2,
    z: f32,
    /// How the depth changes across the frame, so that the z-test compares
    /// depths at pixel centres: a surface seen at a grazing angle changes
    /// depth by more than the tolerance within one pixel, and depths taken
    /// where the samples fall would let the nearer part of every pixel win.
    grad: Vec2,
    /// The footprint's sides; zero where the sample lands on one pixel.
    sides: [Vec2; 2],
    /// The world point at the frame's time (a direction for sky).
    point: Vec3,
    /// Radiance (blended with the twin's where it carries it), the weight
    /// in time and the time value it stands for.
    radiance: Vec3,
    in_time: f32,
    alpha: f32,
    pixel: u32,
    sky: bool,
}

/// The band of frame rows a task deposits into.
struct Band<'a> {
    y0: u32,
    width: u32,
    hot: &'a mut [Hot],
    alpha: &'a mut [f32],
    /// Base pixels left out by nearest-first blending.
    hidden: usize,
}

impl Band<'_> {
    /// Adds `sample` (of `s`) to pixel `(px, py)` of the band (the caller
    /// keeps to the band), at the depth of `s` at the pixel's centre.
    #[inline(always)]
    fn deposit(
        &mut self,
        s: &Splat,
        sample: &Sample,
        (px, py): (i64, i64),
        area: f32,
        covers: bool,
        settings: &WarpSettings,
    ) {
        let j = ((py as u32 - self.y0) * self.width + px as u32) as usize;
        let centre = Vec2::new(px as f32 + 0.5, py as f32 + 0.5);
        let z = if s.sky {
            s.z
        } else {
            (s.z + s.grad.dot(centre - s.px)).clamp(0.5 * s.z, 2.0 * s.z)
        };
        sample.deposit(
            &mut self.hot[j],
            self.alpha.get_mut(j),
            z,
            area,
            covers,
            settings.tolerance,
            settings.blend,
        );
    }
}

/// Weight of a base pixel that mixes the light of objects that have moved
/// apart: small enough that any other sample outweighs it.
const TORN_WEIGHT: f32 = 1e-3;

/// Whether two motions (none: the object stays) move points alike.
fn same_motion(a: Option<Affine3A>, b: Option<Affine3A>) -> bool {
    let a = a.unwrap_or(Affine3A::IDENTITY);
    let b = b.unwrap_or(Affine3A::IDENTITY);
    a.abs_diff_eq(b, 1e-5 * (1.0 + a.translation.abs().max_element()))
}

/// Which of a base pixel's neighbours along a row or column lie on its
/// surface.
#[derive(Clone, Copy)]
enum Hands {
    Both,
    After,
    Before,
}

/// Projects the tile's pixels (and a ring of their neighbours, which give
/// the footprints' sides) into `out`.
fn prepare_tile(
    target: &Target,
    pass: &Pass,
    t: usize,
    settings: &WarpSettings,
    scratch: &mut Vec<Option<Projected>>,
    layers: &mut [Vec<f32>; 2],
    out: &mut Vec<Splat>,
) {
    out.clear();
    let base = pass.base;
    let tile = &base.tiles[t];
    let all_shared = pass.tile_shared(t);
    let (bw, bh) = (base.width(), base.height());
    // The tile's pixels with a ring of their neighbours: a footprint's side
    // comes from the neighbour after the pixel or, where that one lies
    // across a depth break, from the one before it.
    let (xs, ys) = (tile.x0.saturating_sub(1), tile.y0.saturating_sub(1));
    let x_end = (tile.x0 + TILE + 1).min(bw);
    let y_end = (tile.y0 + TILE + 1).min(bh);
    let sw = x_end - xs;
    // A point at the frame's time.
    let moved = |o: u32, p: Vec3| match pass.moves.get(o as usize).and_then(Option::as_ref) {
        Some(m) => m.transform_point3(p),
        None => p,
    };
    scratch.clear();
    for y in ys..y_end {
        for x in xs..x_end {
            let k = (y * bw + x) as usize;
            let p = base.points[k];
            let o = base.object[k];
            let projected = if o == SKY {
                if p == Vec3::ZERO || !settings.sky {
                    None
                } else {
                    target.direction(p).map(|px| Projected {
                        px,
                        z: SKY_Z,
                        object: SKY,
                        primitive: SKY,
                    })
                }
            } else {
                target.point(moved(o, p)).map(|(px, z)| Projected {
                    px,
                    z,
                    object: o,
                    primitive: base.primitive[k],
                })
            };
            scratch.push(projected);
        }
    }
    // The tile's radiance (and the twin's) as f32, converted a row at a
    // time: one call per row lets the half-float conversion use the CPU's
    // vector instructions where it has them.
    let tw = (tile.x0 + TILE).min(bw) - tile.x0;
    let twin = match pass.twin {
        Some(Twin::Carries { base, .. }) => Some(base),
        _ => None,
    };
    let wanted: [Option<&[[f16; 3]]>; 2] = [Some(&base.radiance), twin.map(|b| &b.radiance[..])];
    for (layer, out) in wanted.iter().zip(layers.iter_mut()) {
        let Some(layer) = layer else { continue };
        out.resize((3 * tw * TILE) as usize, 0.0);
        for y in tile.y0..(tile.y0 + TILE).min(bh) {
            let k = (y * bw + tile.x0) as usize;
            let row = 3 * ((y - tile.y0) * tw) as usize;
            layer[k..k + tw as usize]
                .as_flattened()
                .convert_to_f32_slice(&mut out[row..row + 3 * tw as usize]);
        }
    }
    let [rad, twin_rad] = &*layers;
    let layer = |l: &[f32], x: u32, y: u32, scale: f32| {
        let i = 3 * ((y - tile.y0) * tw + (x - tile.x0)) as usize;
        Vec3::from_slice(&l[i..i + 3]) * scale
    };
    let eps = settings.tolerance;
    // Neighbours on one triangle are one plane, however steeply the base
    // saw it; others must agree in depth (pinterp's test).
    let agrees = |a: &Projected, b: &Projected| {
        a.sky() == b.sky()
            && (a.sky()
                || (a.object == b.object
                    && (a.primitive == b.primitive || (a.z - b.z).abs() <= 2.0 * eps * a.z)))
    };
    // A base pixel beside another object's holds some of that object's
    // light (its samples spread over the pixel). Where the two have moved
    // apart since the base's time, that light would be carried to the wrong
    // place, a line along the pixel's object (the short box's lit top drawn
    // across the tall box behind it), so such a pixel only counts where
    // nothing else covers the frame pixel.
    let motion = |o: u32| pass.moves.get(o as usize).copied().flatten();
    let torn = |x: u32, y: u32, o: u32| {
        let own = motion(o);
        [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)]
            .iter()
            .any(|&(dx, dy)| {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                if nx < xs as i64 || ny < ys as i64 || nx >= x_end as i64 || ny >= y_end as i64 {
                    return false;
                }
                let n = scratch[((ny as u32 - ys) * sw + (nx as u32 - xs)) as usize];
                let other = n.map_or(SKY, |n| n.object);
                other != o && !same_motion(own, if other == SKY { None } else { motion(other) })
            })
    };
    for y in tile.y0..(tile.y0 + TILE).min(bh) {
        for x in tile.x0..(tile.x0 + TILE).min(bw) {
            let li = ((y - ys) * sw + (x - xs)) as usize;
            let Some(s) = scratch[li] else { continue };
            let k = (y * bw + x) as usize;
            let shared = all_shared || pass.shared(k);
            if shared && matches!(pass.twin, Some(Twin::CarriedBy(_))) {
                continue;
            }
            // Offset and depth change to an agreeing neighbour, `d` pixels
            // along the base's rows (`row`) or columns, after the pixel or
            // else (negated) before it, and whether the neighbours on both
            // hands agree.
            let neighbour = |row: bool| -> (Option<(Vec2, f32)>, Hands) {
                // The offset to the neighbour `d` pixels on where it agrees;
                // and whether it shows the pixel's object at all.
                let step = |d: i64| -> (Option<(Vec2, f32)>, bool) {
                    let (nx, ny) = if row {
                        (x as i64 + d, y as i64)
                    } else {
                        (x as i64, y as i64 + d)
                    };
                    if nx < xs as i64 || ny < ys as i64 || nx >= x_end as i64 || ny >= y_end as i64
                    {
                        return (None, false);
                    }
                    let Some(n) = scratch[((ny as u32 - ys) * sw + (nx as u32 - xs)) as usize]
                    else {
                        return (None, false);
                    };
                    let offset = ((n.px - s.px) * d as f32, (n.z - s.z) * d as f32);
                    (agrees(&s, &n).then_some(offset), n.object == s.object)
                };
                // Past an edge of its own object (another face of a box)
                // the surface goes on to the edge: only another object's
                // pixel beyond makes the pixel the last of its surface.
                match (step(1), step(-1)) {
                    ((Some(after), _), (Some(_), _) | (None, true)) => (Some(after), Hands::Both),
                    ((Some(after), _), (None, false)) => (Some(after), Hands::After),
                    ((None, true), (before, _)) => (before, Hands::Both),
                    ((None, false), (before, _)) => (before, Hands::Before),
                }
            };
            let ((n1, hands1), (n2, hands2)) = (neighbour(true), neighbour(false));
            let mut centre = s.px;
            let sides = if settings.splat {
                let short = |e: Vec2| e.abs().max_element() <= MAX_SPLAT;
                // A base pixel's own size in the frame, as if it faced the
                // base: how far its surface can reach past its last sample.
                let natural = || {
                    let side = if s.sky() {
                        target.pixel_side(base, base.camera.position + base.points[k], 1.0)
                    } else {
                        target.pixel_side(base, base.points[k], s.z)
                    };
                    side.min(MAX_SPLAT)
                };
                let (e1, e2) = (
                    n1.map(|n| n.0).filter(|e| short(*e)),
                    n2.map(|n| n.0).filter(|e| short(*e)),
                );
                // The footprint is centred on the pixel's projection, so that
                // a base pixel projected into its own camera covers exactly
                // its own pixel. Where only one hand's neighbour agrees, the
                // pixel is the last of its surface: on the other hand its
                // footprint reaches no farther than the base pixel's own
                // size, for a surface the base saw at a grazing angle spans
                // many frame pixels a base pixel, and half of that past its
                // edge would lay it over what lies beyond (a line of the
                // short box's top drawn across the wall behind).
                let mut one_handed = |e: Vec2, hands: Hands| -> Vec2 {
                    let reach = || (0.5 * natural() / e.length().max(1e-6)).min(0.5);
                    // The neighbour is at +e (after) or −e (before); the
                    // footprint spans [−reach, ½] or [−½, reach] of e.
                    let (lo, hi) = match hands {
                        Hands::Both => return e,
                        Hands::After => (-reach(), 0.5),
                        Hands::Before => (-0.5, reach()),
                    };
                    centre += e * (0.5 * (lo + hi));
                    e * (hi - lo)
                };
                // A side with no agreeing neighbour on either hand (a sliver
                // one base pixel wide) is the other side turned a quarter, no
                // longer than the base pixel's own size, or, for a lone
                // pixel, that size: a frame pixel there would widen every
                // thin foreground object over the gaps beside it.
                match (e1, e2) {
                    (Some(a), Some(b)) => [one_handed(a, hands1), one_handed(b, hands2)],
                    (Some(a), None) => {
                        let a = one_handed(a, hands1);
                        [a, a.perp().normalize_or_zero() * a.length().min(natural())]
                    }
                    (None, Some(b)) => {
                        let b = one_handed(b, hands2);
                        [-b.perp().normalize_or_zero() * b.length().min(natural()), b]
                    }
                    (None, None) => {
                        let side = natural();
                        [Vec2::X * side, Vec2::Y * side]
                    }
                }
            } else {
                [Vec2::ZERO; 2]
            };
            let grad = match (n1, n2) {
                (Some((e1, d1)), Some((e2, d2))) if e1.perp_dot(e2).abs() > 1e-6 => {
                    let det = e1.perp_dot(e2);
                    Vec2::new(d1 * e2.y - d2 * e1.y, e1.x * d2 - e2.x * d1) / det
                }
                (Some((e, d)), _) | (None, Some((e, d))) if e.length_squared() > 1e-12 => {
                    e * (d / e.length_squared())
                }
                _ => Vec2::ZERO,
            };
            let mut radiance = layer(rad, x, y, base.scale);
            let (mut in_time, mut alpha) = (pass.weight, pass.alpha);
            if torn(x, y, s.object) {
                in_time *= TORN_WEIGHT;
            }
            if let (
                true,
                Some(Twin::Carries {
                    base: twin,
                    weight,
                    alpha: twin_alpha,
                }),
            ) = (shared, pass.twin)
            {
                // Nearest-first blending keeps the nearer time's value
                // alone, as if the twin's sample had arrived second.
                if settings.blend == Blend::Average {
                    let sum = pass.weight + weight;
                    radiance =
                        (radiance * pass.weight + layer(twin_rad, x, y, twin.scale) * weight) / sum;
                    alpha = (pass.alpha * pass.weight + twin_alpha * weight) / sum;
                    in_time = sum;
                }
            }
            out.push(Splat {
                px: centre,
                z: s.z + grad.dot(centre - s.px),
                grad,
                sides,
                point: if s.sky() {
                    base.points[k]
                } else {
                    moved(s.object, base.points[k])
                },
                radiance,
                in_time,
                alpha,
                pixel: k as u32,
                sky: s.sky(),
            });
        }
    }
}

/// Deposits a tile's samples in the band's pixels.
fn deposit_splats(
    target: &Target,
    (index, pass): (u32, &Pass),
    splats: &[Splat],
    settings: &WarpSettings,
    band: &mut Band,
) {
    let base = pass.base;
    let fw = target.camera.width;
    let cull = settings.culls();
    // Nearest first, a sample that only overlaps a pixel never changes a
    // covered one, and an uncovered pixel is a hole: only covering
    // deposits count, whatever the filter.
    let filter = match settings.blend {
        Blend::Nearest => Filter::Cover,
        Blend::Average => settings.filter,
    };
    let y0 = band.y0;
    let y1 = y0 + band.hot.len() as u32 / fw;
    let eps = settings.tolerance;
    let cam = target.camera.position;
    // Nearest first, a pixel takes one covering sample's radiance whole:
    // weights by angle, time and area would scale it and divide out again.
    let weighted = settings.blend == Blend::Average;
    let in_band = |px: i64, py: i64| px >= 0 && py >= y0 as i64 && px < fw as i64 && py < y1 as i64;
    for s in splats {
        let [e1, e2] = s.sides;
        // Rows a pixel beyond the footprint's bounds cannot be reached
        // (samples of a tile that other bands share mostly land there).
        let reach = 0.5 * (e1.y.abs() + e2.y.abs()) + 1.0;
        if s.px.y + reach < y0 as f32 || s.px.y - reach > y1 as f32 {
            continue;
        }
        let (fx, fy) = (floor(s.px.x), floor(s.px.y));
        let det = e1.perp_dot(e2);
        let footprint = (det.abs() >= 1e-6).then(|| {
            let extent = e1.abs() + e2.abs();
            let (lo, hi) = (s.px - 0.5 * extent, s.px + 0.5 * extent);
            let (rows, cols) = match filter {
                Filter::Box => (
                    (floor(lo.y).max(y0 as i64), ceil(hi.y).min(y1 as i64) - 1),
                    (floor(lo.x).max(0), ceil(hi.x).min(fw as i64) - 1),
                ),
                // Only pixels whose centres the bounds hold (and the pixel
                // under the sample) can be covered.
                Filter::Cover => (
                    (
                        ceil(lo.y - 0.5).min(fy).max(y0 as i64),
                        floor(hi.y - 0.5).max(fy).min(y1 as i64 - 1),
                    ),
                    (
                        ceil(lo.x - 0.5).min(fx).max(0),
                        floor(hi.x - 0.5).max(fx).min(fw as i64 - 1),
                    ),
                ),
            };
            (e1, e2, det, extent, rows, cols)
        });
        // What lands outside the band (the band's neighbours deposit the
        // tiles they share with it too) costs no more than this.
        match footprint {
            Some((.., (ya, yb), (xa, xb))) if ya > yb || xa > xb => continue,
            None if !in_band(fx, fy) => continue,
            _ => {}
        }
        // Where the pixels it could decide already hold nearer or equal
        // samples of earlier bases, nearest-first blending keeps them: the
        // rest of the sample's work would change nothing.
        let named = tag(
            index,
            if s.sky {
                SKY
            } else {
                base.object[s.pixel as usize]
            },
        );
        if cull && hidden_sample(s, footprint.as_ref(), (fx, fy), band, eps, named) {
            band.hidden += 1;
            continue;
        }
        // Weight: how close the base's ray is to the frame's ray, 1/sin of
        // the angle between them (sky: the same direction), times the
        // weight in time.
        let weight = if !weighted {
            1.0
        } else if s.sky {
            MAX_WEIGHT * s.in_time
        } else {
            let k = s.pixel as usize;
            let (a, b) = (base.points[k] - base.camera.position, s.point - cam);
            let sin2 = a.cross(b).length_squared() / (a.length_squared() * b.length_squared());
            (1.0 / sin2).sqrt().min(MAX_WEIGHT) * s.in_time
        };
        let sample = Sample {
            weight,
            radiance: s.radiance,
            alpha: s.alpha,
            pixel: s.pixel,
            tag: named,
        };
        let mut deposit = |px: i64, py: i64, area: f32, covers: bool| {
            band.deposit(s, &sample, (px, py), area, covers, settings);
        };
        let Some((e1, e2, det, extent, (ya, yb), (xa, xb))) = footprint else {
            deposit(fx, fy, 1.0, true);
            continue;
        };
        let origin = s.px - 0.5 * (e1 + e2);
        // Area weights: each frame pixel averages the base pixels over it
        // by how much of it they cover (a box filter of the base's pixels,
        // as the reference's pixels integrate the scene), not by whose
        // centres fall in it, which shifts edges by up to half a pixel. The
        // overlap is that of an axis-aligned box with the footprint's area
        // and the proportions of its bounds (not needed nearest first).
        let area_box = weighted.then(|| {
            let half = 0.5 * extent * (det.abs() / (extent.x * extent.y)).sqrt();
            (s.px - half, s.px + half)
        });
        let overlap = |p: i64, l: f32, h: f32| (h.min(p as f32 + 1.0) - l.max(p as f32)).max(0.0);
        let inv = 1.0 / det;
        for py in ya..=yb {
            let oy = area_box.map(|(bl, bh)| overlap(py, bl.y, bh.y));
            for px in xa..=xb {
                let c = Vec2::new(px as f32 + 0.5, py as f32 + 0.5) - origin;
                // Parallelogram coordinates, half-open so that each pixel
                // centre is covered by one footprint of a surface.
                let a = c.perp_dot(e2) * inv;
                let b = e1.perp_dot(c) * inv;
                // The pixel under the sample has it whole where the
                // footprint is smaller than a pixel.
                let covers =
                    (0.0..1.0).contains(&a) && (0.0..1.0).contains(&b) || (px, py) == (fx, fy);
                let area = match (area_box, oy) {
                    (Some((bl, bh)), Some(oy)) => oy * overlap(px, bl.x, bh.x),
                    _ => 1.0,
                };
                // Slivers below the rounding of positions are no overlap; a
                // covering footprint's sample counts even where the box
                // approximating it misses the pixel.
                if covers {
                    deposit(px, py, area.max(MIN_AREA), true);
                } else if filter == Filter::Box && area > MIN_AREA {
                    deposit(px, py, area, false);
                }
            }
        }
    }
}

/// Whether a sample's covering deposits (the pixels whose centres its
/// footprint's bounds hold, and the pixel under it, both in the band) would
/// all meet pixels of the band covered by samples it is not nearer than (by
/// the tolerance, where they show its object, `tag`'s): under nearest-first
/// blending it then
/// changes nothing (overlapping deposits never change a covered pixel).
/// Its depth over the footprint is bounded by the footprint's corners,
/// between which the depth is linear.
fn hidden_sample(
    s: &Splat,
    footprint: Option<&Footprint>,
    (fx, fy): (i64, i64),
    band: &Band,
    eps: f32,
    tag: u32,
) -> bool {
    let clamp = |z: f32| {
        if s.sky {
            s.z
        } else {
            z.clamp(0.5 * s.z, 2.0 * s.z)
        }
    };
    let at = |c: Vec2| clamp(s.z + s.grad.dot(c - s.px));
    let centre = |px: i64, py: i64| Vec2::new(px as f32 + 0.5, py as f32 + 0.5);
    // Under nearest-first blending a footprint's rows and columns are
    // those of the covering filter, clipped to the band.
    let (mut low, rows, cols) = match footprint {
        None => (at(centre(fx, fy)), (fy, fy), (fx, fx)),
        Some(&(e1, e2, _, _, rows, cols)) => {
            // The depth is linear over the footprint, least at a corner.
            let (g1, g2) = (s.grad.dot(e1), s.grad.dot(e2));
            let corner = s.z - 0.5 * (g1 + g2) + g1.min(0.0) + g2.min(0.0);
            (at(centre(fx, fy)).min(clamp(corner)), rows, cols)
        }
    };
    // Rounding of the depths at pixel centres against the corners'.
    low *= 1.0 - 1e-5;
    (rows.0..=rows.1).all(|py| {
        let row = (py - band.y0 as i64) as usize * band.width as usize;
        band.hot[row + cols.0 as usize..=row + cols.1 as usize]
            .iter()
            .all(|a| a.covered() && low >= a.z * if a.same_object(tag) { 1.0 - eps } else { 1.0 })
    })
}

/// A sample's footprint: its sides, their cross product, its bounds'
/// extent, and the rows and columns its deposits reach.
type Footprint = (Vec2, Vec2, f32, Vec2, (i64, i64), (i64, i64));

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

/// `⌊x⌋` without a call into libm (x86-64's baseline has no rounding
/// instruction), for the positions of splats, which are far inside `i64`.
#[inline]
fn floor(x: f32) -> i64 {
    let i = x as i64;
    i - ((i as f32) > x) as i64
}

#[inline]
fn ceil(x: f32) -> i64 {
    let i = x as i64;
    i + ((i as f32) < x) as i64
}

/// One base pixel's contribution.
struct Sample {
    weight: f32,
    radiance: Vec3,
    alpha: f32,
    /// The base pixel, and its pass and object, as [`Hot`] names them.
    pixel: u32,
    tag: u32,
}

impl Sample {
    /// Adds the sample, weighted by the share `area` of the pixel its
    /// footprint overlaps (and its `alpha` to the pixel's sum, where one is
    /// kept). A sample whose footprint `covers` the pixel's centre replaces
    /// what only overlapping samples put there unless it agrees with it in
    /// depth; one that merely overlaps never displaces a covering one (so
    /// foreground edges do not spill over the background) and joins it
    /// only within the tolerance.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn deposit(
        &self,
        a: &mut Hot,
        alpha: Option<&mut f32>,
        z: f32,
        area: f32,
        covers: bool,
        eps: f32,
        blend: Blend,
    ) {
        let w = self.weight * area;
        // Samples of one object within the tolerance are one surface; of
        // two objects (a box standing on the floor, close in depth along
        // the line where they meet) the nearer one is in front.
        let same = a.same_object(self.tag);
        let nearer = z < if same { a.z * (1.0 - eps) } else { a.z };
        let within = same && !nearer && z <= a.z * (1.0 + eps);
        let replace = a.z == 0.0
            || match (covers, a.covered()) {
                // Nearest first, a covering sample still decides a pixel
                // that only the edges of others overlapped.
                (true, false) => !within || blend == Blend::Nearest,
                (false, true) => false,
                _ => nearer,
            };
        if replace {
            *a = Hot {
                z,
                w,
                radiance: self.radiance * w,
                best: w,
                pixel: self.pixel,
                tag: self.tag | covers as u32,
            };
            if let Some(alpha) = alpha {
                *alpha = self.alpha * w;
            }
        } else if within && blend == Blend::Average {
            a.w += w;
            a.radiance += self.radiance * w;
            if let Some(alpha) = alpha {
                *alpha += self.alpha * w;
            }
            a.z = a.z.min(z);
            a.tag |= covers as u32;
            if w > a.best {
                a.best = w;
                a.pixel = self.pixel;
                a.tag = self.tag | (a.tag & 1);
            }
        }
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// A floor seen at an angle, 3.3 to 4.2 units away, behind what an
    /// earlier base put at each pixel: its nearest point is nearer than
    /// most of those by far more than the tolerance, so only its slab shows
    /// that it is hidden; where it is nearer than what the pixels hold, it
    /// is not.
    #[test]
    fn a_slab_shows_a_tile_seen_at_an_angle_hidden_where_it_is() {
        use super::super::base::Slab;
        let camera = Camera::look_at(
            Vec3::ZERO,
            Vec3::new(0.0, -0.5, -1.0),
            Vec3::Y,
            Projection::Perspective { vfov_deg: 60.0 },
            64,
            64,
        )
        .unwrap();
        let target = Target::new(camera);
        let n = TILE as usize + 1;
        let points: Vec<Vec3> = (0..n * n)
            .map(|k| {
                let (i, j) = ((k % n) as f32 / TILE as f32, (k / n) as f32 / TILE as f32);
                Vec3::new(-0.5 + i, -1.0, -4.0 + j)
            })
            .collect();
        let mut bounds = Bounds::EMPTY;
        for p in &points {
            bounds.grow(*p);
        }
        let slab = Slab::fit(&points, &vec![0; n * n], n, 0);
        assert!(slab.half_width < 1e-5, "{slab:?}");
        assert!((slab.normal.y.abs() - 1.0).abs() < 1e-6, "{slab:?}");
        let mut tile = Tile {
            x0: 0,
            y0: 0,
            fixed: Some(bounds),
            moving: Vec::new(),
            sky: None,
            slabs: vec![(None, slab)],
        };
        let reach = target.tile_reach(&tile, &[]).unwrap();
        // Each pixel holds the floor's distance along its ray times
        // `scale`, or a nearer surface above the horizon.
        let frame = |scale: f32| -> Vec<Hot> {
            (0..64 * 64)
                .map(|k| {
                    let (x, y) = ((k % 64) as f32 + 0.5, (k / 64) as f32 + 0.5);
                    let ray = target.camera.ray(x, y).unwrap();
                    let d = ray.dir.normalize();
                    let z = if d.y < -1e-3 { -1.0 / d.y } else { 0.5 };
                    Hot {
                        z: z * scale,
                        tag: 1,
                        ..Hot::default()
                    }
                })
                .collect()
        };
        let eps = 0.02;
        // The same answers pixel by pixel and cell by cell.
        let test = |tile: &Tile, hot: &[Hot]| {
            let mut cells = Cells::default();
            cells.build((64, 64), (0, 64), target.focal, |j| Some(hot[j].z));
            let by_pixel = hidden(&target, (tile, &[]), (hot, None), 0, &reach, eps);
            let by_cell = hidden(&target, (tile, &[]), (hot, Some(&cells)), 0, &reach, eps);
            assert_eq!(by_pixel, by_cell);
            by_pixel
        };
        let behind = frame(1.0);
        assert!(test(&tile, &behind));
        let farther = frame(1.0 / (1.0 - 1.5 * eps));
        assert!(!test(&tile, &farther));
        tile.slabs.clear();
        assert!(!test(&tile, &behind));
    }

    /// A moving object's slab, moved with it, still holds its points.
    #[test]
    fn a_moved_slab_holds_the_moved_points() {
        use super::super::base::Slab;
        let n = 5;
        let points: Vec<Vec3> = (0..n * n)
            .map(|k| {
                Vec3::new(
                    (k % n) as f32,
                    0.3 * (k / n) as f32,
                    2.0 + 0.1 * (k / n) as f32,
                )
            })
            .collect();
        let slab = Slab::fit(&points, &vec![7; n * n], n, 7);
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::splat(1.5),
            glam::Quat::from_euler(glam::EulerRot::XYZ, 0.4, -1.1, 2.0),
            Vec3::new(3.0, -2.0, 10.0),
        );
        let moved = slab.moved(&m);
        assert!((moved.normal.length() - 1.0).abs() < 1e-5, "{moved:?}");
        for p in &points {
            let q = m.transform_point3(*p);
            let off = (moved.normal.dot(q) - moved.offset).abs();
            assert!(off <= moved.half_width + 1e-4, "{q}: {off} from {moved:?}");
        }
        // The points span the plane: a slab that is not moved misses them.
        let q = m.transform_point3(points[n * n - 1]);
        assert!((slab.normal.dot(q) - slab.offset).abs() > 0.1);
    }

    /// Points in a row make no triangle: their plane is unknown, and a
    /// plane guessed through them would bound nothing their footprints
    /// reach.
    #[test]
    fn points_that_make_no_triangle_have_no_slab() {
        use super::super::base::Slab;
        let points: Vec<Vec3> = (0..9)
            .map(|k| Vec3::new((k % 3) as f32, (k / 3) as f32, -3.0))
            .collect();
        let mut keys = vec![1; 9];
        for k in [1, 2, 4, 5, 7, 8] {
            keys[k] = 2;
        }
        // Key 1 holds the first column of a 3-wide grid.
        let slab = Slab::fit(&points, &keys, 3, 1);
        assert!(slab.half_width.is_infinite(), "{slab:?}");
        let slab = Slab::fit(&points, &keys, 3, 2);
        assert!(slab.half_width.is_finite(), "{slab:?}");
    }

    #[test]
    fn floor_and_ceil_agree_with_libm() {
        for x in [
            -2.5f32, -2.0, -0.5, -0.0, 0.0, 0.3, 1.0, 1.7, 511.99, 512.0, -1e-7, 1e-7,
        ] {
            assert_eq!(floor(x), x.floor() as i64, "floor {x}");
            assert_eq!(ceil(x), x.ceil() as i64, "ceil {x}");
        }
    }
}
