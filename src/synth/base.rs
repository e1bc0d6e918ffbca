//! A base image as synthesis holds it: what does not change from frame to
//! frame computed once (each pixel's world point, bounds of tiles of them),
//! radiance in half floats. 26 bytes per pixel ([`BYTES_PER_PIXEL`]): a
//! 2,544² sphere base takes 168 MB, eight of them 1.35 GB. The bake's
//! light layers stay in its files: re-shading evaluates direct light anew
//! and reads only the radiance.
//!
//! A partial base holds a window of its projection (see
//! `bake::window`): its camera carries the window, so its pixel indices,
//! tiles and blocks count from the window's corner, `camera.ray` and
//! `camera.project` map them to and from the whole projection, and the
//! projection's pixel size stays that of the whole image. The window's
//! corner lies on the block grid, so its tiles and blocks are the whole
//! image's, in the same order.

use std::collections::HashMap;
use std::sync::Arc;

use anyhow::{ensure, Result};
use glam::Vec3;
use half::f16;
use rayon::prelude::*;

use crate::bake::Bake;
use crate::camera::Camera;
use crate::image::planes_file::{to_half, BasePlanes};
use crate::image::{RangeImage, NO_HIT};
use crate::scene::Scene;

/// Side of the square tiles whose bounds cull what a frame cannot see.
pub const TILE: u32 = 16;

/// Side, in tiles, of the blocks culled before their tiles: a frame sees a
/// few percent of a sphere base, and testing every tile of the rest cost a
/// tenth of a frame.
const BLOCK: u32 = 8;

// A window cornered on the block grid cuts the same tiles and blocks as
// the whole image: its frames are the whole image's, bit for bit.
const _: () = assert!(crate::bake::window::ALIGN.is_multiple_of(TILE * BLOCK));
const _: () = assert!(crate::bake::window::STEP.is_multiple_of(TILE));

/// Point, object id, primitive id (4 bytes each, the point 12) and
/// radiance (3 half floats).
pub const BYTES_PER_PIXEL: usize = 12 + 4 + 4 + 6;

/// Axis-aligned bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub lo: Vec3,
    pub hi: Vec3,
}

impl Bounds {
    pub(super) const EMPTY: Bounds = Bounds {
        lo: Vec3::splat(f32::INFINITY),
        hi: Vec3::splat(f32::NEG_INFINITY),
    };

    pub(super) fn grow(&mut self, p: Vec3) {
        self.lo = self.lo.min(p);
        self.hi = self.hi.max(p);
    }

    fn is_empty(&self) -> bool {
        self.lo.x > self.hi.x
    }

    pub fn corners(&self) -> [Vec3; 8] {
        let (a, b) = (self.lo, self.hi);
        [
            Vec3::new(a.x, a.y, a.z),
            Vec3::new(b.x, a.y, a.z),
            Vec3::new(a.x, b.y, a.z),
            Vec3::new(b.x, b.y, a.z),
            Vec3::new(a.x, a.y, b.z),
            Vec3::new(b.x, a.y, b.z),
            Vec3::new(a.x, b.y, b.z),
            Vec3::new(b.x, b.y, b.z),
        ]
    }
}

/// The world points of one tile of base pixels, with the pixels to its
/// right and below (the far corners of its pixels' splats).
#[derive(Clone, Debug)]
pub struct Tile {
    pub x0: u32,
    pub y0: u32,
    /// Points of objects that never move.
    pub fixed: Option<Bounds>,
    /// Points of each moving object, by object id.
    pub moving: Vec<(u32, Bounds)>,
    /// Directions of the pixels that see nothing (their `points` are unit
    /// directions): they project as points at infinity.
    pub sky: Option<Bounds>,
    /// For the fixed points (`None`) and each moving object's (at the
    /// base's time), the slab holding them: it bounds the depth of the
    /// tile's samples pixel by pixel of a frame, where the bounds give one
    /// nearest depth for the whole tile, which a surface seen at an angle
    /// is far behind over most of its projection.
    pub slabs: Vec<(Option<u32>, Slab)>,
}

/// Points `p` with `|normal · p − offset| ≤ half_width`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slab {
    pub normal: Vec3,
    pub offset: f32,
    pub half_width: f32,
}

impl Slab {
    /// All of space: the slab of points that make no triangle, whose
    /// plane is unknown.
    const UNBOUNDED: Slab = Slab {
        normal: Vec3::Z,
        offset: 0.0,
        half_width: f32::INFINITY,
    };

    /// The slab of the points of a grid (`width` a row) whose `keys` are
    /// `key`, around the plane through their centroid whose normal is the
    /// sum of the normals of the triangles that neighbouring such points
    /// make (all of space where they make none). Thin where they lie on one
    /// plane; wider (a weaker bound, never a wrong one) where they do not.
    pub(super) fn fit(points: &[Vec3], keys: &[u32], width: usize, key: u32) -> Slab {
        let mut normal = Vec3::ZERO;
        let (mut sum, mut n) = (Vec3::ZERO, 0);
        for (k, p) in points.iter().enumerate() {
            if keys[k] != key {
                continue;
            }
            sum += *p;
            n += 1;
            let (right, down) = (k + 1, k + width);
            if (k + 1) % width != 0
                && down < points.len()
                && keys[right] == key
                && keys[down] == key
            {
                normal += (points[right] - *p).cross(points[down] - *p);
            }
        }
        let Some(normal) = normal.try_normalize() else {
            return Slab::UNBOUNDED;
        };
        let offset = normal.dot(sum / n.max(1) as f32);
        let half_width = points
            .iter()
            .zip(keys)
            .filter(|(_, k)| **k == key)
            .map(|(p, _)| (normal.dot(*p) - offset).abs())
            .fold(0.0, f32::max);
        Slab {
            normal,
            offset,
            half_width,
        }
    }

    /// The slab of the points moved by the affine map `m`.
    pub fn moved(&self, m: &glam::Affine3A) -> Slab {
        // n · p = (A⁻ᵀ n) · (A p + t − t).
        let normal = m.matrix3.inverse().transpose() * glam::Vec3A::from(self.normal);
        let length = normal.length();
        let normal = Vec3::from(normal / length);
        Slab {
            normal,
            offset: (self.offset + length * normal.dot(Vec3::from(m.translation))) / length,
            half_width: self.half_width / length,
        }
    }
}

/// The union of a square of tiles' bounds.
#[derive(Clone, Debug)]
pub struct Block {
    /// Its first tile's column and row in the base's grid of tiles.
    pub tx: u32,
    pub ty: u32,
    pub fixed: Option<Bounds>,
    pub sky: Option<Bounds>,
    /// Whether a tile of it holds a moving object: such blocks are not
    /// culled whole, their moved tiles are.
    pub moving: bool,
}

/// What a pixel holds where its ray meets no surface: `point` is then the
/// ray's unit direction, or zero where the projection covers no direction
/// (outside a fisheye's circle).
pub const SKY: u32 = NO_HIT;

/// One base image, ready to be projected.
#[derive(Debug)]
pub struct Base {
    /// Index of the image in the bake's manifest.
    pub image: usize,
    pub view: usize,
    pub time: f32,
    pub camera: Camera,
    /// World point at `time` of each pixel's first hit (see [`SKY`]).
    pub points: Vec<Vec3>,
    pub object: Vec<u32>,
    pub primitive: Vec<u32>,
    /// Radiance divided by `scale`.
    pub radiance: Vec<[f16; 3]>,
    /// A power of two that brings the brightest radiance within half-float
    /// range, whatever the scene's intensities.
    pub scale: f32,
    pub tiles: Vec<Tile>,
    pub blocks: Vec<Block>,
}

/// `img` with the pixels beside the scene's lights given the light of
/// neighbours of like normal (`lights::unmix_beside_lights`), on the
/// radiance the halves hold: a half times the power-of-two scale is exact
/// in 32 bits and scales back to the same half, so the pixels re-lit take
/// their neighbours' halves and the others keep theirs.
fn unmix_beside_lights(scene: &Scene, img: BasePlanes) -> BasePlanes {
    let (scale, inv) = (img.scale, 1.0 / img.scale);
    let mut range = RangeImage {
        width: img.width,
        height: img.height,
        radiance: img
            .radiance
            .par_iter()
            .map(|h| from_half(h) * scale)
            .collect(),
        distance: img.distance,
        object_id: img.object_id,
        primitive_id: img.primitive_id,
        normal: img.normal,
        meta: img.meta,
    };
    let radiance = if super::lights::unmix_beside_lights(scene, &mut range) > 0 {
        range
            .radiance
            .par_iter()
            .map(|&c| to_half(c, inv))
            .collect()
    } else {
        img.radiance
    };
    BasePlanes {
        width: range.width,
        height: range.height,
        radiance,
        scale,
        distance: range.distance,
        object_id: range.object_id,
        primitive_id: range.primitive_id,
        normal: range.normal,
        meta: range.meta,
    }
}

/// Decoded in software (inlined): `to_f32` asks the CPU for F16C on every
/// value, which costs more than the conversion in the warp's inner loop.
#[inline(always)]
pub fn from_half(c: &[f16; 3]) -> Vec3 {
    Vec3::new(
        c[0].to_f32_const(),
        c[1].to_f32_const(),
        c[2].to_f32_const(),
    )
}

/// Checks that `object_id` names the scene's objects.
fn check_ids(scene: &Scene, image: usize, object_id: &[u32]) -> Result<()> {
    for &o in object_id {
        ensure!(
            o == NO_HIT || (o as usize) < scene.objects.len(),
            "base image {image}: object id {o}, but the scene has {} objects",
            scene.objects.len()
        );
    }
    Ok(())
}

impl Base {
    /// Prepares manifest image `image` of view `view` from the range image.
    pub fn new(scene: &Scene, image: usize, view: usize, img: RangeImage) -> Result<Base> {
        Base::from_planes(scene, image, view, BasePlanes::of(img))
    }

    /// Prepares manifest image `image` of view `view` from what a base
    /// reads of it ([`BasePlanes::of`] the range image, or its planes
    /// file): the same planes make the same base, bit for bit.
    pub fn from_planes(scene: &Scene, image: usize, view: usize, img: BasePlanes) -> Result<Base> {
        let n = img.len();
        let camera = img.meta.camera;
        ensure!(
            camera.width == img.width && camera.height == img.height,
            "base image {image}: its camera is {}x{}, its pixels {}x{}",
            camera.width,
            camera.height,
            img.width,
            img.height
        );
        check_ids(scene, image, &img.object_id)?;
        let img = unmix_beside_lights(scene, img);
        let w = img.width as usize;
        let points: Vec<Vec3> = (0..n)
            .into_par_iter()
            .map(|k| {
                let (x, y) = ((k % w) as f32 + 0.5, (k / w) as f32 + 0.5);
                match camera.ray(x, y) {
                    Some(r) if img.object_id[k] != NO_HIT => r.at(img.distance[k]),
                    Some(r) => r.dir.normalize_or_zero(),
                    None => Vec3::ZERO,
                }
            })
            .collect();
        let moving: Vec<bool> = scene
            .objects
            .iter()
            .map(|o| !o.motion.is_static())
            .collect();
        let tiles = tiles(&camera, &points, &img.object_id, &moving);
        let blocks = blocks(&camera, &tiles);
        Ok(Base {
            image,
            view,
            time: img.meta.time,
            camera,
            points,
            object: img.object_id,
            primitive: img.primitive_id,
            radiance: img.radiance,
            scale: img.scale,
            tiles,
            blocks,
        })
    }

    /// Indices in [`Base::tiles`] of the tiles of `block`.
    pub fn tiles_of(&self, block: &Block) -> impl Iterator<Item = usize> {
        let (tw, th) = (self.width().div_ceil(TILE), self.height().div_ceil(TILE));
        let (tx, ty) = (block.tx, block.ty);
        (ty..(ty + BLOCK).min(th))
            .flat_map(move |y| (tx..(tx + BLOCK).min(tw)).map(move |x| (y * tw + x) as usize))
    }

    pub fn width(&self) -> u32 {
        self.camera.width
    }

    pub fn height(&self) -> u32 {
        self.camera.height
    }

    pub fn bytes(&self) -> usize {
        self.points.len() * BYTES_PER_PIXEL
            + self
                .tiles
                .iter()
                .map(|t| {
                    std::mem::size_of::<Tile>()
                        + 28 * t.moving.len()
                        + std::mem::size_of::<(Option<u32>, Slab)>() * t.slabs.len()
                })
                .sum::<usize>()
            + self.blocks.len() * std::mem::size_of::<Block>()
    }

    #[inline]
    pub fn radiance_at(&self, k: usize) -> Vec3 {
        from_half(&self.radiance[k]) * self.scale
    }
}

/// The key of the fixed points in [`Slab::fit`]'s grid (object ids are
/// below it, [`SKY`] above).
const FIXED: u32 = SKY - 1;

fn tiles(camera: &Camera, points: &[Vec3], object: &[u32], moving: &[bool]) -> Vec<Tile> {
    let (w, h) = (camera.width, camera.height);
    let origins: Vec<(u32, u32)> = (0..h.div_ceil(TILE))
        .flat_map(|ty| (0..w.div_ceil(TILE)).map(move |tx| (tx * TILE, ty * TILE)))
        .collect();
    origins
        .into_par_iter()
        .map(|(x0, y0)| {
            let mut tile = Tile {
                x0,
                y0,
                fixed: None,
                moving: Vec::new(),
                sky: None,
                slabs: Vec::new(),
            };
            let mut fixed = Bounds::EMPTY;
            // The tile's points in grid order, keyed by the group whose
            // slab they join: the fixed points, each moving object's, sky.
            let cap = ((TILE + 1) * (TILE + 1)) as usize;
            let (mut grid, mut keys) = (Vec::with_capacity(cap), Vec::with_capacity(cap));
            let mut sky = Bounds::EMPTY;
            let mut by_object: Vec<(u32, Bounds)> = Vec::new();
            for y in y0..(y0 + TILE + 1).min(h) {
                for x in x0..(x0 + TILE + 1).min(w) {
                    let k = (y * w + x) as usize;
                    let o = object[k];
                    grid.push(points[k]);
                    keys.push(match o {
                        SKY => SKY,
                        o if moving[o as usize] => o,
                        _ => FIXED,
                    });
                    if o == SKY {
                        if points[k] != Vec3::ZERO {
                            sky.grow(points[k]);
                        }
                    } else if moving[o as usize] {
                        match by_object.iter_mut().find(|(id, _)| *id == o) {
                            Some((_, b)) => b.grow(points[k]),
                            None => {
                                let mut b = Bounds::EMPTY;
                                b.grow(points[k]);
                                by_object.push((o, b));
                            }
                        }
                    } else {
                        fixed.grow(points[k]);
                    }
                }
            }
            tile.fixed = (!fixed.is_empty()).then_some(fixed);
            tile.sky = (!sky.is_empty()).then_some(sky);
            tile.moving = by_object;
            let width = ((x0 + TILE + 1).min(w) - x0) as usize;
            if tile.fixed.is_some() {
                tile.slabs
                    .push((None, Slab::fit(&grid, &keys, width, FIXED)));
            }
            for (o, _) in &tile.moving {
                tile.slabs
                    .push((Some(*o), Slab::fit(&grid, &keys, width, *o)));
            }
            tile
        })
        .collect()
}

fn blocks(camera: &Camera, tiles: &[Tile]) -> Vec<Block> {
    let (tw, th) = (camera.width.div_ceil(TILE), camera.height.div_ceil(TILE));
    let union = |a: Option<Bounds>, b: Option<Bounds>| match (a, b) {
        (Some(a), Some(b)) => Some(Bounds {
            lo: a.lo.min(b.lo),
            hi: a.hi.max(b.hi),
        }),
        (a, b) => a.or(b),
    };
    let mut blocks = Vec::new();
    for by in (0..th).step_by(BLOCK as usize) {
        for bx in (0..tw).step_by(BLOCK as usize) {
            let mut block = Block {
                tx: bx,
                ty: by,
                fixed: None,
                sky: None,
                moving: false,
            };
            for ty in by..(by + BLOCK).min(th) {
                for tx in bx..(bx + BLOCK).min(tw) {
                    let tile = &tiles[(ty * tw + tx) as usize];
                    block.fixed = union(block.fixed, tile.fixed);
                    block.sky = union(block.sky, tile.sky);
                    block.moving |= !tile.moving.is_empty();
                }
            }
            blocks.push(block);
        }
    }
    blocks
}

/// Bases read from a bake, kept while they fit a memory budget, the least
/// recently used dropped first.
pub struct BaseCache {
    budget: usize,
    held: HashMap<usize, (Arc<Base>, u64)>,
    clock: u64,
    /// Seconds spent reading and preparing bases.
    pub load_seconds: f64,
    pub loads: usize,
}

impl BaseCache {
    pub fn new(budget_bytes: usize) -> Self {
        Self {
            budget: budget_bytes,
            held: HashMap::new(),
            clock: 0,
            load_seconds: 0.0,
            loads: 0,
        }
    }

    pub fn budget(&self) -> usize {
        self.budget
    }

    pub fn bytes(&self) -> usize {
        self.held.values().map(|(b, _)| b.bytes()).sum()
    }

    /// Base image `k` of the bake's manifest, read and prepared on first
    /// use. Bases that `keep` names are never dropped to make room.
    pub fn get(
        &mut self,
        bake: &Bake,
        scene: &Scene,
        k: usize,
        keep: &[usize],
    ) -> Result<Arc<Base>> {
        self.clock += 1;
        if let Some((b, used)) = self.held.get_mut(&k) {
            *used = self.clock;
            return Ok(b.clone());
        }
        let start = std::time::Instant::now();
        let view = bake
            .manifest
            .images
            .get(k)
            .map(|e| e.view)
            .unwrap_or_default();
        let base = if bake.manifest.has_base_planes() {
            Base::from_planes(scene, k, view, bake.read_base(k)?)?
        } else {
            Base::new(scene, k, view, bake.read_range(k)?)?
        };
        let base = Arc::new(base);
        self.load_seconds += start.elapsed().as_secs_f64();
        self.loads += 1;
        while !self.held.is_empty() && self.bytes() + base.bytes() > self.budget {
            let oldest = self
                .held
                .iter()
                .filter(|(k, _)| !keep.contains(k))
                .min_by_key(|(_, (_, used))| *used)
                .map(|(&k, _)| k);
            match oldest {
                Some(o) => {
                    self.held.remove(&o);
                }
                None => break,
            }
        }
        self.held.insert(k, (base.clone(), self.clock));
        Ok(base)
    }
}
