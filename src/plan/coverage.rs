//! Coverage fitness of a view-space cell (beyond the paper).
//!
//! The paper's fitness asks whether the corners see the same object in the
//! same *direction*. In a furnished room any object nearer than the room's
//! far side shifts across directions between corners, so that fitness
//! stays low for cells far smaller than reprojection needs: in the soda
//! shop cells of 0.6 × 0.1 × 0.5 m agree on under 42% of their pixels,
//! although each corner's range image puts every surface it sees where a
//! frame inside the cell sees it. What reprojection cannot do is show a
//! surface its bases do not see. So this fitness asks the paper's question
//! of surfaces instead of directions: the fraction of the directions from
//! the cell's centre (the point farthest from its corners) whose first
//! surface every corner sees, by shadow rays from that surface point to
//! each corner. Directions that meet nothing count as seen, as pixels that
//! see nothing agree in the paper's: synthesis traces the sky along the
//! frame's own rays.

use glam::Vec3;
use rayon::prelude::*;

use crate::accel::RayEngine;
use crate::camera::Camera;
use crate::ray::{offset_origin, Ray};

/// Rows per parallel chunk, as for id-images.
const ROWS_PER_BATCH: usize = 4;

/// A shadow ray to a corner stops this short of it (relative): the corner
/// is a point in free space, not a surface to be found.
const SHORT_OF_CORNER: f32 = 1e-4;

/// The fraction of the directions of `centre`'s sphere view whose first
/// surface each of `corners` sees, unoccluded and from the side `centre`
/// sees it from (or that meet nothing). A surface leaves the count at the
/// first corner that does not see it.
pub fn coverage(engine: &dyn RayEngine, centre: &Camera, corners: &[Vec3]) -> f32 {
    let (w, h) = (centre.width as usize, centre.height as usize);
    let rows: Vec<usize> = (0..h).step_by(ROWS_PER_BATCH).collect();
    let (seen, counted) = rows
        .par_iter()
        .map(|&j0| {
            let mut rays = Vec::new();
            for j in j0..(j0 + ROWS_PER_BATCH).min(h) {
                for i in 0..w {
                    if let Some(r) = centre.ray(i as f32 + 0.5, j as f32 + 0.5) {
                        rays.push(r);
                    }
                }
            }
            let mut hits = vec![None; rays.len()];
            engine.intersect_batch(&rays, &mut hits);
            // Surface points every corner so far sees: (point, normal).
            let mut seen: Vec<(Vec3, Vec3)> = rays
                .iter()
                .zip(&hits)
                .filter_map(|(r, h)| h.map(|h| (r.at(h.t), h.normal)))
                .collect();
            let mut blocked = Vec::new();
            let mut shadow = Vec::new();
            for &corner in corners {
                if seen.is_empty() {
                    break;
                }
                // A corner behind the surface (as seen from the centre)
                // sees its back, not what the centre sees.
                seen.retain(|&(p, n)| (corner - p).dot(n) * (centre.position - p).dot(n) > 0.0);
                shadow.clear();
                shadow.extend(seen.iter().map(|&(p, n)| {
                    let origin = offset_origin(p, n, corner - p);
                    let mut ray = Ray::new(origin, corner - origin);
                    ray.tmax = 1.0 - SHORT_OF_CORNER;
                    ray
                }));
                blocked.clear();
                blocked.resize(shadow.len(), true);
                engine.occluded_batch(&shadow, &mut blocked);
                let mut verdicts = blocked.iter();
                seen.retain(|_| !*verdicts.next().expect("one verdict a point"));
            }
            let sky = hits.iter().filter(|h| h.is_none()).count();
            (sky + seen.len(), rays.len())
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    if counted == 0 {
        1.0
    } else {
        seen as f32 / counted as f32
    }
}
