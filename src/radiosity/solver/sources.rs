//! Direct irradiance from the lights that are not surfaces: point lights
//! (intensity cos / r²) and the sun (radiance × solid angle × cos), each
//! seen through shadow rays from points of the element. Emitting surfaces
//! reach elements through the links instead (see `linear`).

use glam::Vec3;
use rayon::prelude::*;

use super::hierarchy::Hierarchy;
use super::links::{hash3, unit};
use crate::accel::RayEngine;
use crate::ray::{offset_origin, Ray};
use crate::scene::{Light, PointArrival};

/// Direct irradiance `[front, back]` on each surface node in `nodes`, from
/// `points` sample points each, and the number of shadow rays traced.
pub fn direct(
    h: &Hierarchy,
    nodes: &[u32],
    lights: &[Light],
    engine: &dyn RayEngine,
    points: usize,
) -> (Vec<[Vec3; 2]>, u64) {
    if lights.is_empty() {
        return (vec![[Vec3::ZERO; 2]; nodes.len()], 0);
    }
    let out: Vec<([Vec3; 2], u64)> = nodes
        .par_chunks(64)
        .flat_map_iter(|chunk| {
            let mut rays = Vec::new();
            // (node in chunk, side, irradiance if unblocked)
            let mut terms = Vec::new();
            for (k, &i) in chunk.iter().enumerate() {
                let n = h.node(i);
                for j in 0..points {
                    let x = point_in(n.tri, i, j, points);
                    for light in lights {
                        let (shadow, e, cos) = match *light {
                            Light::Point {
                                position,
                                intensity,
                            } => {
                                let Some(a) = PointArrival::new(position, intensity, x, n.normal)
                                else {
                                    continue;
                                };
                                let cos = n.normal.dot(a.wi);
                                (a.shadow, a.irradiance * cos.abs(), cos)
                            }
                            Light::Sun {
                                direction,
                                radiance,
                                angular_diameter_deg,
                            } => {
                                let w = direction.normalize_or_zero();
                                let cos = n.normal.dot(w);
                                let omega = Light::sun_solid_angle(angular_diameter_deg);
                                let shadow = Ray::new(offset_origin(x, n.normal, w), w);
                                (shadow, radiance * omega * cos.abs(), cos)
                            }
                        };
                        if cos == 0.0 || !e.is_finite() || e == Vec3::ZERO {
                            continue;
                        }
                        rays.push(shadow);
                        terms.push((k, usize::from(cos < 0.0), e / points as f32));
                    }
                }
            }
            let mut blocked = vec![false; rays.len()];
            engine.occluded_batch(&rays, &mut blocked);
            let mut acc = vec![[Vec3::ZERO; 2]; chunk.len()];
            for (&(k, side, e), &b) in terms.iter().zip(&blocked) {
                if !b {
                    acc[k][side] += e;
                }
            }
            let n = rays.len() as u64;
            acc.into_iter()
                .enumerate()
                .map(move |(k, a)| (a, if k == 0 { n } else { 0 }))
        })
        .collect();
    let rays = out.iter().map(|o| o.1).sum();
    (out.into_iter().map(|o| o.0).collect(), rays)
}

/// The j-th of n stratified points in triangle `t`.
fn point_in(t: [Vec3; 3], seed: u32, j: usize, n: usize) -> Vec3 {
    if n == 1 {
        return (t[0] + t[1] + t[2]) / 3.0;
    }
    let mut a = (j as f32 + unit(hash3(seed, j as u32, 7))) / n as f32;
    let mut b = unit(hash3(seed, j as u32, 8));
    if a + b > 1.0 {
        (a, b) = (1.0 - a, 1.0 - b);
    }
    t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b
}
