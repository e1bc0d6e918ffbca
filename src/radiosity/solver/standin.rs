//! Coarsened patches moved onto the surfaces they stand for.
//!
//! A coarsened object's patches cut across its true surface: the chords of
//! a sphere lie inside it. The solver traces visibility in the full scene,
//! so every shadow ray from such a patch started inside the real sphere and
//! was blocked: the bronze sculpture of the studio received next to no light
//! and reflected none, and rooms full of coarsened furniture came out dark.
//! Each patch is lifted along its normal onto the object's true surface,
//! found by one ray from outside the simplifier's error bound.

use glam::{Affine3A, Vec3};
use rayon::prelude::*;

use crate::accel::RayEngine;
use crate::radiosity::simplify::COARSEN_ERROR;
use crate::radiosity::{object_extent, Simplified};
use crate::ray::Ray;
use crate::scene::Scene;

/// World-space displacement of each patch of `s` posed by `poses`: from its
/// centroid to the first surface of its own object met coming back along
/// its normal from as far out as the coarsening may have moved it (and no
/// farther than half the patch's longest edge, so that a patch is not
/// carried onto another part of its object). Zero where that ray meets
/// another object or a surface facing another way first, or nothing.
pub fn lifts(
    scene: &Scene,
    s: &Simplified,
    poses: &[Affine3A],
    engine: &dyn RayEngine,
) -> Vec<Vec3> {
    let bound: Vec<f32> = scene
        .objects
        .iter()
        .map(|o| COARSEN_ERROR * object_extent(&o.mesh.positions))
        .collect();
    s.patches
        .par_iter()
        .map(|p| {
            let xf = poses[p.object as usize];
            let t = p.vertices.map(|v| xf.transform_point3(v));
            let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero();
            let longest = (0..3)
                .map(|k| t[k].distance(t[(k + 1) % 3]))
                .fold(0.0f32, f32::max);
            let scale = xf
                .matrix3
                .x_axis
                .length()
                .max(xf.matrix3.y_axis.length())
                .max(xf.matrix3.z_axis.length());
            let reach = (bound[p.object as usize] * scale).min(0.5 * longest);
            if !(reach > 0.0 && reach.is_finite()) || n == Vec3::ZERO {
                return Vec3::ZERO;
            }
            let c = (t[0] + t[1] + t[2]) / 3.0;
            let ray = Ray::segment(c + n * reach, n * (-2.0 * reach), 1.0);
            match engine.intersect(&ray) {
                Some(hit) if hit.object == p.object && hit.normal.dot(n) > 0.5 => {
                    let lift = ray.at(hit.t) - c;
                    if lift.is_finite() {
                        lift
                    } else {
                        Vec3::ZERO
                    }
                }
                _ => Vec3::ZERO,
            }
        })
        .collect()
}
