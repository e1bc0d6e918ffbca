//! Irradiance records looked up at shading points, with normal-aware
//! weights as Radiance interpolates its ambient cache.
//!
//! Each record `i` has a position `p_i`, normal `n_i`, irradiance `E_i`, a
//! radius `R_i` (the longest edge of the patches it is a corner of: the
//! extent of surface it stands for) and a translational gradient fitted to
//! its neighbours on the same face (Ward & Heckbert 1992). At a point `p`
//! with normal `n` on the same object, the records are weighted as in
//! Ward's irradiance cache,
//!
//! `e_i = |p - p_i| / R_i + sqrt(1 - n·n_i)`, `w_i = 1/e_i - 1/A`,
//!
//! over the records with `e_i < A` (`A = 1.5`, so every point of a patch
//! sees its three corners; the `- 1/A` makes weights fall to zero at the
//! edge of a record's range, so nothing jumps when a record enters it).
//! Records facing more than 30° away from `n`, or lying off the tangent
//! plane by more than half their radius, are not used: light does not leak
//! round a crease nor between stacked surfaces. Each record contributes its
//! value extrapolated by its gradient, so a linear field on a plane is
//! reproduced exactly; a record whose extrapolation turns negative (a
//! gradient fitted across a shadow edge) is left out, as Radiance does.
//!
//! Where no record is in range, the range is widened until the record of
//! smallest `e_i` facing the same hemisphere enters it (the same weights
//! with every `e_i` divided by the smallest); an object without records
//! (pruned by the simplification) or a point facing away from all of them
//! gets the area-weighted average over the lit records, as Radiance's
//! `-av` ambient value stands in for a missing cache.
//!
//! Lookups are what the multipass renderer does at every diffuse hit in
//! place of a traced bounce, so they should cost about what the shadow ray
//! traced there costs. Each side of each
//! object has a uniform grid over its records' ranges; a cell holds, in
//! record order, a copy of every record whose range (the ball of radius
//! `A R_i` and the slab within `R_i / 2` of its tangent plane) reaches
//! into the cell, four records to a block, field by field. A lookup finds
//! its cell by arithmetic and weighs four records at a time, without
//! searching, branching per record or allocating; the weighted terms are
//! summed in record order, so the result is the same as weighing every
//! record of the side, bit for bit.

use glam::{BVec4A, Vec3, Vec4};

use super::{record_sides, Simplified};

/// Acceptance bound on Ward's error estimate `e_i`.
const ACCEPT: f32 = 1.5;
/// Records whose normal is further than 30° from the query's are not used.
const MIN_COS: f32 = 0.866;
/// Relative margin on a record's reach when cells are assigned, far above
/// the rounding of the distance and error computed at lookup, so that no
/// record whose `e_i < A` at a point is missing from that point's cell.
const REACH_MARGIN: f32 = 1e-3;
/// A grid's cells and blocks per record (a block is 304 bytes): beyond
/// them the cells are coarsened (by √2) rather than memory spent. The
/// Cornell box's large faces at q = 0.6 would need 73–94 blocks per record
/// at the finest size, 33–40 at the next.
const CELLS_PER_RECORD: f64 = 256.0;
const BLOCKS_PER_RECORD: f64 = 48.0;

/// The records of one time, searchable per object and side in object space.
pub struct IrradianceCache {
    records: Vec<Entry>,
    /// Per object, the front side's grid and the back's. A side's lookup
    /// never meets the other side's records, which sit at the same points.
    grids: Vec<[Grid; 2]>,
    /// Where each cell's blocks start in `blocks` (each grid's cells
    /// followed by one closing offset).
    cells: Vec<usize>,
    blocks: Vec<Block>,
    /// Every usable record of each grid's side, in record order: what the
    /// fallback searches where no record is in range.
    members: Vec<u32>,
    average: Vec3,
}

struct Entry {
    position: Vec3,
    normal: Vec3,
    value: Vec3,
    /// `d E_c / d p` for each colour channel `c`, in the tangent plane.
    gradient: [Vec3; 3],
    radius: f32,
}

/// Four records, field by field, for weighing them at once; unused lanes
/// have a zero normal, which no query faces.
#[derive(Clone, Copy)]
struct Block {
    position: [Vec4; 3],
    normal: [Vec4; 3],
    /// `1 / R_i`: a multiplication is cheaper than a division.
    inv_radius: Vec4,
    value: [Vec4; 3],
    /// `gradient[c][k]`: `d E_c / d x_k`.
    gradient: [[Vec4; 3]; 3],
}

impl Block {
    /// The records `ids` (at most four) of `records`.
    fn new(records: &[Entry], ids: &[u32]) -> Self {
        let mut lanes = [[0.0f32; 4]; 19];
        for (l, &i) in ids.iter().enumerate() {
            let r = &records[i as usize];
            let [g0, g1, g2] = r.gradient;
            let fields = [r.position, r.normal, r.value, g0, g1, g2]
                .into_iter()
                .flat_map(|v| v.to_array())
                .chain([1.0 / r.radius.max(f32::MIN_POSITIVE)]);
            for (lane, x) in lanes.iter_mut().zip(fields) {
                lane[l] = x;
            }
        }
        let v = |k: usize| Vec4::from_array(lanes[k]);
        let v3 = |k: usize| [v(k), v(k + 1), v(k + 2)];
        Self {
            position: v3(0),
            normal: v3(3),
            value: v3(6),
            gradient: [v3(9), v3(12), v3(15)],
            inv_radius: v(18),
        }
    }
}

/// A uniform grid over the records of one side of one object.
#[derive(Clone, Copy, Default)]
struct Grid {
    lo: Vec3,
    /// Cells per unit length.
    scale: f32,
    dims: [usize; 3],
    /// This grid's first offset in `IrradianceCache::cells`.
    first_cell: usize,
    /// This grid's range of `IrradianceCache::members`.
    members: (usize, usize),
}

impl Grid {
    /// Position of `x` along `axis` in cells, whose integer part (where
    /// not negative) is the cell. The build assigns records to cells
    /// through this same function, which only grows with `x`, so a point
    /// inside a record's reach lands in a cell the record was given.
    fn coord(&self, x: f32, axis: usize) -> f32 {
        (x - self.lo[axis]) * self.scale
    }

    /// Index of the cell holding `p`, if any.
    fn cell(&self, p: Vec3) -> Option<usize> {
        let mut index = 0;
        for axis in (0..3).rev() {
            let c = self.coord(p[axis], axis);
            // Also false for NaN and infinities.
            if !(c >= 0.0 && c < self.dims[axis] as f32) {
                return None;
            }
            index = index * self.dims[axis] + (c as usize).min(self.dims[axis] - 1);
        }
        Some(index)
    }

    /// The cells along each axis that the box of half-width `reach` about
    /// `p` overlaps, clamped to the grid.
    fn span(&self, p: Vec3, reach: f32) -> ([usize; 3], [usize; 3]) {
        let clamp = |c: f32, k: usize| (c.max(0.0) as usize).min(self.dims[k] - 1);
        (
            [0, 1, 2].map(|k| clamp(self.coord(p[k] - reach, k), k)),
            [0, 1, 2].map(|k| clamp(self.coord(p[k] + reach, k), k)),
        )
    }

    /// The cells that record `r`'s range reaches: its ball of radius
    /// `reach` and the slab of half-width `R_i / 2` about its tangent
    /// plane, each tested against the cell's box widened by `pad`.
    fn reached_cells(&self, r: &Entry, reach: f32, pad: f32, out: &mut Vec<usize>) {
        out.clear();
        let size = 1.0 / self.scale;
        let slab = 0.5 * r.radius * (1.0 + REACH_MARGIN);
        let (a, b) = self.span(r.position, reach);
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                for x in a[0]..=b[0] {
                    let c = Vec3::new(x as f32, y as f32, z as f32);
                    let box_lo = self.lo + c * size - pad;
                    let box_hi = self.lo + (c + 1.0) * size + pad;
                    let nearest = r.position.clamp(box_lo, box_hi);
                    if nearest.distance_squared(r.position) > reach * reach {
                        continue;
                    }
                    let centre = (box_lo + box_hi) * 0.5;
                    let half = (box_hi - box_lo) * 0.5;
                    let offset = (centre - r.position).dot(r.normal).abs();
                    if offset - half.dot(r.normal.abs()) > slab {
                        continue;
                    }
                    out.push((z * self.dims[1] + y) * self.dims[0] + x);
                }
            }
        }
    }
}

impl IrradianceCache {
    /// `indirect[i]` is the irradiance of `simplified.records[i]`; values
    /// for another set of records (another length) are an error, since
    /// pairing them up by index would light the scene with wrong values.
    pub fn new(simplified: &Simplified, indirect: &[Vec3]) -> anyhow::Result<Self> {
        let n = simplified.records.len();
        anyhow::ensure!(
            indirect.len() == n,
            "irradiance cache: {} irradiance values for {n} records",
            indirect.len()
        );
        let value = |i: usize| {
            let v = indirect[i];
            if v.is_finite() {
                v.max(Vec3::ZERO)
            } else {
                Vec3::ZERO
            }
        };
        // Neighbours across patches, longest incident edge, and area share.
        let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); n];
        let mut radius = vec![0.0f32; n];
        let mut area = vec![0.0f64; n];
        for p in &simplified.patches {
            let [a, b, c] = p.vertices;
            let longest = (b - a).length().max((c - b).length()).max((a - c).length());
            let share = p.area() as f64 / 3.0;
            for side in p.sides() {
                for i in side {
                    let i = i as usize;
                    if i >= n || !longest.is_finite() {
                        continue;
                    }
                    radius[i] = radius[i].max(longest);
                    if share.is_finite() {
                        area[i] += share;
                    }
                    for &j in &side {
                        if j as usize != i && (j as usize) < n && !neighbours[i].contains(&j) {
                            neighbours[i].push(j);
                        }
                    }
                }
            }
        }
        // Over the records light reaches: the unlit sides (a room's outside,
        // a box's inside) are no part of what a missing record stands for.
        let lit: Vec<usize> = (0..n).filter(|&i| value(i) != Vec3::ZERO).collect();
        let total_area: f64 = lit.iter().map(|&i| area[i]).sum();
        let average = if lit.is_empty() {
            Vec3::ZERO
        } else if total_area > 0.0 {
            let s = lit
                .iter()
                .fold(glam::DVec3::ZERO, |s, &i| s + value(i).as_dvec3() * area[i]);
            (s / total_area).as_vec3()
        } else {
            lit.iter().map(|&i| value(i)).sum::<Vec3>() / lit.len() as f32
        };

        let records: Vec<Entry> = (0..n)
            .map(|i| {
                let r = &simplified.records[i];
                let normal = r.normal.normalize_or_zero();
                let gradient = fit_gradient(i, &simplified.records, &neighbours[i], value);
                Entry {
                    position: r.position,
                    normal,
                    value: value(i),
                    gradient,
                    radius: radius[i],
                }
            })
            .collect();

        let mut cache = Self {
            records,
            grids: Vec::new(),
            cells: Vec::new(),
            blocks: Vec::new(),
            members: Vec::new(),
            average,
        };
        let sides = side_members(simplified, &cache.records);
        cache.grids = sides
            .iter()
            .map(|s| s.each_ref().map(|m| cache.add_grid(m)))
            .collect();
        Ok(cache)
    }

    /// Indirect irradiance at object-space point `p` with unit normal `n` on
    /// the `front` (by winding) or back side of `object`.
    pub fn irradiance(&self, object: u32, front: bool, p: Vec3, n: Vec3) -> Vec3 {
        let n = n.normalize_or_zero();
        let Some(sides) = self.grids.get(object as usize) else {
            return self.average;
        };
        let grid = &sides[usize::from(!front)];
        let members = &self.members[grid.members.0..grid.members.1];
        if members.is_empty() || !p.is_finite() || n == Vec3::ZERO || !n.is_finite() {
            return self.average;
        }
        let blocks = grid.cell(p).map_or(&[][..], |c| {
            let c = grid.first_cell + c;
            &self.blocks[self.cells[c]..self.cells[c + 1]]
        });
        blend(blocks, p, n).unwrap_or_else(|| self.nearest(members, p, n))
    }

    /// Error estimate of record `i` for the fallback: any record facing
    /// the query's hemisphere, wherever it lies.
    fn reach_error(&self, i: usize, p: Vec3, n: Vec3) -> Option<f32> {
        let r = &self.records[i];
        let cos = n.dot(r.normal);
        if cos <= 0.0 {
            return None;
        }
        let e = (p - r.position).length() / r.radius.max(f32::MIN_POSITIVE)
            + (1.0 - cos).max(0.0).sqrt();
        e.is_finite().then_some(e)
    }

    /// Where no record is in range: the range widened until the nearest
    /// record (by error estimate) facing the same hemisphere enters it
    /// (Ward weights with every `e_i` divided by the smallest); else the
    /// scene average. Searches every record of the side, which is rare
    /// enough (points beyond the records' ranges, or at creases) to cost
    /// little overall, and exact.
    fn nearest(&self, members: &[u32], p: Vec3, n: Vec3) -> Vec3 {
        let mut closest: Option<(f32, usize)> = None;
        for &i in members {
            let i = i as usize;
            if let Some(e) = self.reach_error(i, p, n) {
                if closest.is_none_or(|(e_min, _)| e < e_min) {
                    closest = Some((e, i));
                }
            }
        }
        let Some((e_min, closest)) = closest else {
            return self.average;
        };
        if e_min <= 0.0 {
            return self.records[closest].value;
        }
        let (mut sum, mut wsum) = (Vec3::ZERO, 0.0f32);
        for &i in members {
            let i = i as usize;
            let Some(e) = self.reach_error(i, p, n) else {
                continue;
            };
            let w = e_min / e - 1.0 / ACCEPT;
            if w > 0.0 {
                sum += self.records[i].value * w;
                wsum += w;
            }
        }
        let v = sum / wsum;
        if wsum > 0.0 && v.is_finite() {
            v
        } else {
            self.average
        }
    }

    /// The area-weighted average indirect irradiance of the lit records: what points
    /// without usable records get.
    pub fn average(&self) -> Vec3 {
        self.average
    }

    /// Builds the grid over `members` (usable records of one side, in
    /// record order), appending its cells and blocks.
    fn add_grid(&mut self, members: &[u32]) -> Grid {
        let first_member = self.members.len();
        self.members.extend_from_slice(members);
        let mut grid = Grid {
            members: (first_member, self.members.len()),
            first_cell: self.cells.len(),
            ..Grid::default()
        };
        let reach = |r: &Entry| ACCEPT * r.radius * (1.0 + REACH_MARGIN);
        let (lo, hi) = members
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &i| {
                let r = &self.records[i as usize];
                (lo.min(r.position - reach(r)), hi.max(r.position + reach(r)))
            });
        let extent = hi - lo;
        if members.is_empty() || !extent.is_finite() {
            // No cells: every lookup falls back to the members.
            self.cells.push(self.blocks.len());
            return grid;
        }
        let mut radii: Vec<f32> = members
            .iter()
            .map(|&i| self.records[i as usize].radius)
            .collect();
        radii.sort_by(f32::total_cmp);
        // Cells of about a third of the typical record radius where memory
        // allows: a cell then holds not many more records than are in range
        // at any of its points. Finer cells hold fewer, but their copies no
        // longer stay in cache (a quarter of the radius is slower on the
        // Cornell box); half the radius is about a quarter slower.
        let mut size = 0.35 * radii[radii.len() / 2];
        let m = members.len() as f64;
        grid.lo = lo;
        let lists = loop {
            grid.scale = 1.0 / size;
            grid.dims = [0, 1, 2].map(|a| ((extent[a] / size).ceil() as usize).max(1));
            let cells: f64 = grid.dims.iter().map(|&d| d as f64).product();
            // The boxes overlapped bound the records copied from above.
            let boxes: f64 = members
                .iter()
                .map(|&i| {
                    let r = &self.records[i as usize];
                    let (a, b) = grid.span(r.position, reach(r));
                    (0..3).map(|k| (b[k] - a[k] + 1) as f64).product::<f64>()
                })
                .sum();
            let coarser = size * std::f32::consts::SQRT_2;
            if !coarser.is_finite() {
                break self.lists(&grid, members, lo, hi);
            }
            if cells > CELLS_PER_RECORD * m || boxes > 16.0 * BLOCKS_PER_RECORD * m {
                size = coarser;
                continue;
            }
            let lists = self.lists(&grid, members, lo, hi);
            let blocks: usize = lists.iter().map(|l| l.len().div_ceil(4)).sum();
            if blocks as f64 <= BLOCKS_PER_RECORD * m {
                break lists;
            }
            size = coarser;
        };
        for list in &lists {
            self.cells.push(self.blocks.len());
            self.blocks
                .extend(list.chunks(4).map(|ids| Block::new(&self.records, ids)));
        }
        self.cells.push(self.blocks.len());
        grid
    }

    /// Each cell's records, in record order.
    fn lists(&self, grid: &Grid, members: &[u32], lo: Vec3, hi: Vec3) -> Vec<Vec<u32>> {
        // Cell boxes are widened for the rounding of `Grid::cell` at the
        // magnitude of the grid's coordinates.
        let size = 1.0 / grid.scale;
        let pad = size * REACH_MARGIN + lo.abs().max(hi.abs()).max_element() * 1e-6;
        let reach = |r: &Entry| ACCEPT * r.radius * (1.0 + REACH_MARGIN);
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); grid.dims.iter().product()];
        let mut hits = Vec::new();
        for &i in members {
            let r = &self.records[i as usize];
            grid.reached_cells(r, reach(r), pad, &mut hits);
            for &c in &hits {
                lists[c].push(i);
            }
        }
        lists
    }
}

/// Ward's weighted average over the records of `blocks` in range of
/// `(p, n)`, summed in order; `None` where none is. The four records of a
/// block are weighed at once, without a branch per record; each lane's
/// arithmetic is the same whatever the arrangement of records into blocks.
fn blend(blocks: &[Block], p: Vec3, n: Vec3) -> Option<Vec3> {
    let [px, py, pz] = p.to_array().map(Vec4::splat);
    let [nx, ny, nz] = n.to_array().map(Vec4::splat);
    let mut sum = Vec4::ZERO;
    for b in blocks {
        let cos = nx * b.normal[0] + ny * b.normal[1] + nz * b.normal[2];
        let d = [px - b.position[0], py - b.position[1], pz - b.position[2]];
        // Distance off the record's tangent plane.
        let off = (d[0] * b.normal[0] + d[1] * b.normal[1] + d[2] * b.normal[2]).abs();
        let length = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        let e = length * b.inv_radius + sqrt((Vec4::ONE - cos).max(Vec4::ZERO));
        // The value carried by the gradient, or as recorded where that
        // overflows; a negative one is left out.
        let near = cos.cmpge(Vec4::splat(MIN_COS))
            & (off * b.inv_radius).cmple(Vec4::splat(0.5))
            // Also false for a NaN or infinite `e`.
            & e.cmplt(Vec4::splat(ACCEPT));
        let v = [0, 1, 2].map(|c| {
            let g = b.gradient[c];
            let v = b.value[c] + (g[0] * d[0] + g[1] * d[1] + g[2] * d[2]);
            Vec4::select(v.abs().cmplt(Vec4::INFINITY), v, b.value[c])
        });
        let used: BVec4A = near & v[0].min(v[1]).min(v[2]).cmpge(Vec4::ZERO);
        let exact = used & e.cmple(Vec4::splat(1e-6));
        if exact.any() {
            let lane = exact.bitmask().trailing_zeros() as usize;
            return Some(Vec3::new(v[0][lane], v[1][lane], v[2][lane]));
        }
        let w = Vec4::select(used, Vec4::ONE / e - Vec4::splat(1.0 / ACCEPT), Vec4::ZERO);
        // One lane after the other, so that the sum does not depend on
        // which lane a record sits in.
        let [r, g, b, w] = [v[0] * w, v[1] * w, v[2] * w, w].map(|x| x.to_array());
        for (((r, g), b), w) in r.into_iter().zip(g).zip(b).zip(w) {
            sum += Vec4::new(r, g, b, w);
        }
    }
    let v = sum.truncate() / sum.w;
    (sum.w > 0.0 && v.is_finite()).then_some(v)
}

/// Square roots of four lanes, in a form the compiler vectorizes.
fn sqrt(x: Vec4) -> Vec4 {
    Vec4::from_array(x.to_array().map(f32::sqrt))
}

/// Least-squares gradient of record `i`'s value over its neighbours on
/// the same face, in the record's tangent plane. Fewer than two
/// independent neighbours: no gradient.
fn fit_gradient(
    i: usize,
    records: &[super::RecordPoint],
    neighbours: &[u32],
    value: impl Fn(usize) -> Vec3,
) -> [Vec3; 3] {
    let r = &records[i];
    let n = r.normal.normalize_or_zero();
    let v0 = value(i);
    if n == Vec3::ZERO || !n.is_finite() {
        return [Vec3::ZERO; 3];
    }
    let frame = crate::bsdf::Frame::new(n);
    // Normal equations of the 2D fit, accumulated in f64.
    let (mut sxx, mut sxy, mut syy) = (0.0f64, 0.0f64, 0.0f64);
    let mut bx = glam::DVec3::ZERO;
    let mut by = glam::DVec3::ZERO;
    let mut used = 0;
    for &j in neighbours {
        let j = j as usize;
        let o = &records[j];
        if o.object != r.object || o.normal.normalize_or_zero().dot(n) < MIN_COS {
            continue;
        }
        let d = frame.to_local(o.position - r.position);
        if !d.is_finite() {
            continue;
        }
        let (x, y) = (d.x as f64, d.y as f64);
        let dv = (value(j) - v0).as_dvec3();
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
        bx += dv * x;
        by += dv * y;
        used += 1;
    }
    let det = sxx * syy - sxy * sxy;
    // Collinear neighbours leave the gradient across them undetermined.
    if used < 2 || det.is_nan() || det <= 1e-9 * (sxx + syy) * (sxx + syy) {
        return [Vec3::ZERO; 3];
    }
    let gx = (bx * syy - by * sxy) / det;
    let gy = (by * sxx - bx * sxy) / det;
    let g = |c: usize| {
        let v = frame.to_world(Vec3::new(gx[c] as f32, gy[c] as f32, 0.0));
        if v.is_finite() {
            v
        } else {
            Vec3::ZERO
        }
    };
    [g(0), g(1), g(2)]
}

/// Each object's usable records per side (front, back), in record order.
/// A record serves the sides its patches name it for (both where it stands
/// for both, or no patch names it); records without a position, normal or
/// extent are not searched.
fn side_members(simplified: &Simplified, records: &[Entry]) -> Vec<[Vec<u32>; 2]> {
    let objects = simplified
        .records
        .iter()
        .map(|r| r.object as usize + 1)
        .max()
        .unwrap_or(0);
    let sides = record_sides(simplified);
    let mut members: Vec<[Vec<u32>; 2]> = vec![Default::default(); objects];
    for (i, (rp, e)) in simplified.records.iter().zip(records).enumerate() {
        if !(e.position.is_finite() && e.radius > 0.0 && e.radius.is_finite())
            || e.normal == Vec3::ZERO
        {
            continue;
        }
        for (side, bit) in [(0, 1u8), (1, 2)] {
            if sides[i] == 0 || sides[i] & bit != 0 {
                members[rp.object as usize][side].push(i as u32);
            }
        }
    }
    members
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::radiosity::formfactor::subdivide;
    use crate::rng::Pcg32;
    use crate::scene::Scene;

    /// The Cornell box cut unevenly (each triangle 4-way zero to three
    /// times, T-junctions and all), scaled by `scale` and moved by
    /// `offset`, so that record radii vary within and between objects.
    fn uneven_box(scale: f32, offset: Vec3) -> (Scene, Simplified) {
        let scene = Scene::load(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/cornell-box/scene.toml"
        ))
        .unwrap();
        let mut triangles: Vec<(u32, [Vec3; 3])> = Vec::new();
        for (o, object) in scene.objects.iter().enumerate() {
            for (k, t) in object.mesh.triangles.iter().enumerate() {
                let t = t.map(|v| object.mesh.positions[v as usize] * scale + offset);
                let mut tris = vec![t];
                for _ in 0..(o + k) % 4 {
                    tris = tris.into_iter().flat_map(subdivide).collect();
                }
                triangles.extend(tris.into_iter().map(|t| (o as u32, t)));
            }
        }
        let s = Simplified::from_triangles(&scene, triangles);
        (scene, s)
    }

    /// Every record of `object` usable on the given side, found without
    /// the grid.
    fn side_of(s: &Simplified, object: u32, front: bool) -> Vec<u32> {
        let sides = record_sides(s);
        let bit = if front { 1 } else { 2 };
        let mut radius = vec![0.0f32; s.records.len()];
        for p in &s.patches {
            let [a, b, c] = p.vertices;
            let longest = (b - a).length().max((c - b).length()).max((a - c).length());
            for i in p.sides().flatten() {
                radius[i as usize] = radius[i as usize].max(longest);
            }
        }
        (0..s.records.len())
            .filter(|&i| {
                let r = &s.records[i];
                r.object == object
                    && radius[i] > 0.0
                    && r.position.is_finite()
                    && r.normal != Vec3::ZERO
                    && (sides[i] == 0 || sides[i] & bit != 0)
            })
            .map(|i| i as u32)
            .collect()
    }

    /// Ward's weighting over every record of the object's side, in record
    /// order (four to a block as they come), then the fallback: what the
    /// grid must reproduce bit for bit.
    fn brute_force(c: &IrradianceCache, ids: &[u32], p: Vec3, n: Vec3) -> (Vec3, bool) {
        let n = n.normalize_or_zero();
        if ids.is_empty() {
            return (c.average(), false);
        }
        let blocks: Vec<Block> = ids.chunks(4).map(|b| Block::new(&c.records, b)).collect();
        match blend(&blocks, p, n) {
            Some(v) => (v, true),
            None => (c.nearest(ids, p, n), false),
        }
    }

    /// A unit vector within about `angle` radians of `n`.
    fn vec3(rng: &mut Pcg32) -> Vec3 {
        Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32())
    }

    fn tilt(n: Vec3, angle: f32, rng: &mut Pcg32) -> Vec3 {
        let r = vec3(rng) * 2.0 - 1.0;
        (n + r * angle.tan()).normalize()
    }

    #[test]
    fn grid_lookup_equals_weighting_every_record() {
        for (scale, offset) in [
            (1.0, Vec3::ZERO),
            (1e-4, Vec3::splat(3e-4)),
            (1e4, Vec3::new(-2e4, 5e3, 0.0)),
        ] {
            let (_, s) = uneven_box(scale, offset);
            let mut rng = Pcg32::for_sample(7, 0, 0);
            let values: Vec<Vec3> = s
                .records
                .iter()
                .map(|r| {
                    let q = (r.position - offset) / scale;
                    let smooth = Vec3::new(1.0 + q.x, 2.0 - q.y, 1.5 + q.z * q.x);
                    // Some records unlit, the rest noisy, so that gradients
                    // cross zero and some extrapolations turn negative.
                    if rng.next_f32() < 0.1 {
                        Vec3::ZERO
                    } else {
                        smooth.abs() * (0.5 + rng.next_f32())
                    }
                })
                .collect();
            let cache = IrradianceCache::new(&s, &values).unwrap();
            let (mut in_range, mut fallback) = (0, 0);
            for object in 0..=s.records.iter().map(|r| r.object).max().unwrap() {
                for front in [true, false] {
                    let ids = side_of(&s, object, front);
                    let patches: Vec<&crate::radiosity::Patch> =
                        s.patches.iter().filter(|p| p.object == object).collect();
                    for k in 0..400 {
                        let patch = patches[k % patches.len()];
                        let [a, b, c] = patch.vertices;
                        let (u, v) = (rng.next_f32(), rng.next_f32());
                        let (u, v) = if u + v > 1.0 {
                            (1.0 - u, 1.0 - v)
                        } else {
                            (u, v)
                        };
                        let mut p = a + (b - a) * u + (c - a) * v;
                        let side_normal = if front {
                            patch.normal()
                        } else {
                            -patch.normal()
                        };
                        // Off the surface by up to an edge, tilted by up to
                        // 40°; every eighth point anywhere near the object
                        // with any normal.
                        let edge = (b - a).length();
                        p += side_normal * edge * (rng.next_f32() - 0.5) * 0.8;
                        let mut n = tilt(side_normal, 0.7 * rng.next_f32(), &mut rng);
                        if k % 8 == 7 {
                            p += (vec3(&mut rng) - 0.5) * 4.0 * edge;
                            n = tilt(Vec3::Z, 1.5, &mut rng);
                        }
                        let got = cache.irradiance(object, front, p, n);
                        let (want, ranged) = brute_force(&cache, &ids, p, n);
                        assert_eq!(
                            got.to_array().map(f32::to_bits),
                            want.to_array().map(f32::to_bits),
                            "object {object} front {front} at {p} n {n}: {got} vs {want}"
                        );
                        if ranged {
                            in_range += 1;
                        } else {
                            fallback += 1;
                        }
                    }
                }
            }
            // Both paths exercised, mostly the grid's.
            assert!(
                in_range > 2 * fallback && fallback > 0,
                "{in_range} {fallback}"
            );
        }
    }
}
