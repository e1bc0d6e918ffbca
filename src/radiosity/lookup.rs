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
//! Where no record is in range, the nearest records facing the same way
//! are blended by `1/e_i`; an object without records (pruned by the
//! simplification) or a point facing away from all of them gets the
//! area-weighted average over the lit records, as Radiance's `-av` ambient
//! value stands in for a missing cache.

use std::collections::BTreeMap;
use std::num::NonZero;

use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};

use super::{record_sides, Simplified};

/// Acceptance bound on Ward's error estimate `e_i`.
const ACCEPT: f32 = 1.5;
/// Records whose normal is further than 30° from the query's are not used.
const MIN_COS: f32 = 0.866;
/// Neighbours considered where no record is in range.
const FALLBACK_NEAREST: usize = 8;

/// The records of one time, searchable per object in object space.
pub struct IrradianceCache {
    records: Vec<Entry>,
    /// Per object and side (front, back), the records grouped by radius
    /// (within a factor of two), so that each group can be searched with
    /// its own range. A side's search never meets the other side's records,
    /// which sit at the same points.
    objects: Vec<[Vec<Level>; 2]>,
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

struct Level {
    /// Largest record radius of the group.
    radius: f32,
    tree: ImmutableKdTree<f32, 3>,
    /// Record index of each tree item.
    ids: Vec<u32>,
}

impl IrradianceCache {
    /// `indirect[i]` is the irradiance of `simplified.records[i]`.
    pub fn new(simplified: &Simplified, indirect: &[Vec3]) -> Self {
        let n = simplified.records.len().min(indirect.len());
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

        let objects = build_levels(simplified, &records);
        Self {
            records,
            objects,
            average,
        }
    }

    /// Indirect irradiance at object-space point `p` with unit normal `n` on
    /// the `front` (by winding) or back side of `object`.
    pub fn irradiance(&self, object: u32, front: bool, p: Vec3, n: Vec3) -> Vec3 {
        let n = n.normalize_or_zero();
        let Some(sides) = self.objects.get(object as usize) else {
            return self.average;
        };
        let levels = &sides[usize::from(!front)];
        if levels.is_empty() || !p.is_finite() || n == Vec3::ZERO || !n.is_finite() {
            return self.average;
        }
        let q = p.to_array();
        let (mut sum, mut wsum) = (Vec3::ZERO, 0.0f32);
        for level in levels {
            let range = ACCEPT * level.radius;
            for nb in level
                .tree
                .within_unsorted::<SquaredEuclidean>(&q, range * range)
            {
                let i = level.ids[nb.item as usize] as usize;
                let Some(e) = self.error(i, p, n) else {
                    continue;
                };
                if e >= ACCEPT {
                    continue;
                }
                let Some(v) = self.extrapolate(i, p) else {
                    continue;
                };
                if e <= 1e-6 {
                    return v;
                }
                let w = 1.0 / e - 1.0 / ACCEPT;
                sum += v * w;
                wsum += w;
            }
        }
        if wsum > 0.0 {
            let v = sum / wsum;
            if v.is_finite() {
                return v;
            }
        }
        self.nearest(levels, p, n)
    }

    /// Ward's error estimate of record `i` at `(p, n)`, or `None` where the
    /// record must not be used (facing away, off the tangent plane).
    fn error(&self, i: usize, p: Vec3, n: Vec3) -> Option<f32> {
        let r = &self.records[i];
        let cos = n.dot(r.normal);
        if cos < MIN_COS {
            return None;
        }
        let d = p - r.position;
        let radius = r.radius.max(f32::MIN_POSITIVE);
        if d.dot(r.normal).abs() > 0.5 * radius {
            return None;
        }
        let e = d.length() / radius + (1.0 - cos).max(0.0).sqrt();
        e.is_finite().then_some(e)
    }

    /// Record `i`'s value carried to `p` by its gradient; `None` where
    /// that turns negative.
    fn extrapolate(&self, i: usize, p: Vec3) -> Option<Vec3> {
        let r = &self.records[i];
        let d = p - r.position;
        let g = Vec3::new(
            r.gradient[0].dot(d),
            r.gradient[1].dot(d),
            r.gradient[2].dot(d),
        );
        let v = r.value + g;
        if !v.is_finite() {
            Some(r.value)
        } else {
            (v.min_element() >= 0.0).then_some(v)
        }
    }

    /// Where no record is in range: the range widened until the nearest
    /// record facing the same hemisphere enters it (Ward weights with
    /// every `e_i` divided by the smallest); else the scene average.
    fn nearest(&self, levels: &[Level], p: Vec3, n: Vec3) -> Vec3 {
        let q = p.to_array();
        let k = NonZero::new(FALLBACK_NEAREST).expect("nonzero");
        let mut found: Vec<(f32, usize)> = Vec::new();
        for level in levels {
            for nb in level.tree.nearest_n::<SquaredEuclidean>(&q, k) {
                let i = level.ids[nb.item as usize] as usize;
                let r = &self.records[i];
                let cos = n.dot(r.normal);
                if cos <= 0.0 {
                    continue;
                }
                let e = (p - r.position).length() / r.radius.max(f32::MIN_POSITIVE)
                    + (1.0 - cos).max(0.0).sqrt();
                if e.is_finite() {
                    found.push((e, i));
                }
            }
        }
        let Some(&(e_min, closest)) = found.iter().min_by(|a, b| a.0.total_cmp(&b.0)) else {
            return self.average;
        };
        if e_min <= 0.0 {
            return self.records[closest].value;
        }
        let (mut sum, mut wsum) = (Vec3::ZERO, 0.0f32);
        for (e, i) in found {
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
    let frame = crate::render::bsdf::Frame::new(n);
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

/// Groups each object's records by side and radius, one tree per power of
/// two. A record serves the sides its patches name it for (both where it
/// stands for both, or no patch names it).
fn build_levels(simplified: &Simplified, records: &[Entry]) -> Vec<[Vec<Level>; 2]> {
    let objects = simplified
        .records
        .iter()
        .map(|r| r.object as usize + 1)
        .max()
        .unwrap_or(0);
    let sides = record_sides(simplified);
    let mut groups: Vec<[BTreeMap<i32, Vec<u32>>; 2]> = vec![Default::default(); objects];
    for (i, (rp, e)) in simplified.records.iter().zip(records).enumerate() {
        if !(e.position.is_finite() && e.radius > 0.0 && e.radius.is_finite())
            || e.normal == Vec3::ZERO
        {
            continue;
        }
        let key = e.radius.log2().ceil() as i32;
        for (side, bit) in [(0, 1u8), (1, 2)] {
            if sides[i] == 0 || sides[i] & bit != 0 {
                groups[rp.object as usize][side]
                    .entry(key)
                    .or_default()
                    .push(i as u32);
            }
        }
    }
    groups
        .into_iter()
        .map(|g| g.map(|g| levels(g, records)))
        .collect()
}

/// One tree per radius group.
fn levels(groups: BTreeMap<i32, Vec<u32>>, records: &[Entry]) -> Vec<Level> {
    groups
        .into_values()
        .map(|ids| {
            let points: Vec<[f32; 3]> = ids
                .iter()
                .map(|&i| records[i as usize].position.to_array())
                .collect();
            Level {
                radius: ids
                    .iter()
                    .map(|&i| records[i as usize].radius)
                    .fold(0.0, f32::max),
                tree: ImmutableKdTree::new_from_slice(&points),
                ids,
            }
        })
        .collect()
}
