//! From leaf elements to records: vertex interpolation of the piecewise
//! constant solution.

use glam::Vec3;

use super::hierarchy::{Hierarchy, NONE};
use crate::radiosity::{record_sides, Simplified};

/// Irradiance `(indirect, direct)` at every record: the area-weighted
/// average over the leaf elements that touch the record's point, over all
/// patches sharing it, so that neighbouring patches agree on shared edges.
/// A patch's front records get its front side, its back records its back
/// side; a record that stands for both sides (`back == corners`) reports
/// the side that receives more light.
///
/// The indirect irradiance is averaged over the leaves' open parts
/// (`open`, each leaf side's share that is not buried, from
/// [`super::links::open_shares`]): a leaf's irradiance is its area
/// average, in which the part behind a chair rail or under a box counts
/// dark, but a record stands for the surface one sees. Summing the leaves'
/// light over their open area, rather than dividing each leaf by its own
/// share, keeps a leaf that is nearly all buried (whose few open points
/// leave that share uncertain) from weighing on its records.
pub fn records(
    s: &Simplified,
    h: &Hierarchy,
    leaf_of: impl Fn(u32) -> usize,
    indirect: &[[Vec3; 2]],
    direct: &[[Vec3; 2]],
    open: &[[f32; 2]],
) -> (Vec<Vec3>, Vec<Vec3>) {
    let n = s.records.len();
    // Per record and side: Σ A·indirect, Σ A·direct, Σ A·open; and Σ A.
    let mut acc = vec![[(Vec3::ZERO, Vec3::ZERO, 0.0f32); 2]; n];
    let mut weight = vec![0.0f32; n];
    for (p, patch) in s.patches.iter().enumerate() {
        for k in 0..3 {
            let leaf = h.corner_leaf(p, k);
            if leaf == NONE {
                continue;
            }
            let a = h.node(leaf).area;
            let l = leaf_of(leaf);
            for records in patch.sides() {
                let rec = records[k] as usize;
                for side in 0..2 {
                    acc[rec][side].0 += indirect[l][side] * a;
                    acc[rec][side].1 += direct[l][side] * a;
                    acc[rec][side].2 += open[l][side] * a;
                }
                weight[rec] += a;
            }
        }
    }
    let mut ind = Vec::with_capacity(n);
    let mut dir = Vec::with_capacity(n);
    for ((sides, w), role) in acc.into_iter().zip(weight).zip(record_sides(s)) {
        if w <= 0.0 {
            ind.push(Vec3::ZERO);
            dir.push(Vec3::ZERO);
            continue;
        }
        let total = |s: usize| (sides[s].0 + sides[s].1).element_sum();
        let side = match role {
            1 => 0,
            2 => 1,
            _ => usize::from(total(1) > total(0)),
        };
        ind.push(sides[side].0 / sides[side].2);
        dir.push(sides[side].1 / w);
    }
    (ind, dir)
}
