//! Direct irradiance from the lights that are not surfaces: point lights
//! (intensity cos / r²) and the sun (radiance × solid angle × cos), each
//! seen through shadow rays from points of the element. Emitting surfaces
//! reach elements through the links instead (see `linear`).
//!
//! The points form a jittered grid. A room lit by the sun through its
//! windows takes nearly all its light from the sunlit patches, and the
//! elements those patches' edges cross decide their total power: with 2–4
//! random points such an element counted none, part or all of its sun by
//! the luck of its points, and the studio's sunlit power, and with it every
//! indirect record, came out a few percent off, a different few at every
//! quality (docs/radiosity.md, "Sunlit power").

use glam::Vec3;
use rayon::prelude::*;

use super::hierarchy::Hierarchy;
use super::links::{hash3, unit};
use crate::accel::RayEngine;
use crate::ray::{offset_origin, Ray};
use crate::scene::{Light, PointArrival};

/// Direct irradiance `[front, back]` on each surface node in `nodes`, from
/// `grid × grid` sample points each, and the number of shadow rays traced.
pub fn direct(
    h: &Hierarchy,
    nodes: &[u32],
    lights: &[Light],
    engine: &dyn RayEngine,
    grid: usize,
) -> (Vec<[Vec3; 2]>, u64) {
    let points = grid * grid;
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
                    let x = point_in(n.tri, i, j, grid);
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

/// The j-th point of a jittered `grid × grid` stratification of triangle
/// `t`, mapped from the unit square by the area-preserving square-root warp
/// (which, unlike folding the square's upper half onto the lower, keeps
/// each cell of the grid on its own part of the triangle).
fn point_in(t: [Vec3; 3], seed: u32, j: usize, grid: usize) -> Vec3 {
    let cell = |k: usize, salt: u32| (k as f32 + unit(hash3(seed, j as u32, salt))) / grid as f32;
    let (u, v) = (cell(j % grid, 7), cell(j / grid, 8));
    let r = u.sqrt();
    t[0] + (t[1] - t[0]) * (1.0 - r) + (t[2] - t[0]) * (v * r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{self, Backend};
    use crate::radiosity::solver::Params;
    use crate::radiosity::{Quality, Simplified};
    use crate::scene::Scene;

    /// A unit floor (two triangles, one element each) in the sun under a
    /// 0.3 m square plate, at 16 places: the sun's power on the floor is
    /// `E cos (1 − 0.09)` exactly (a hard shadow, all of it on the floor).
    ///
    /// Each estimate is wrong only in the grid cells the shadow's four edges
    /// cross: a line crosses at most `2k − 1` cells of a `k × k` grid (both
    /// families of cell sides are straight lines under the warp), each
    /// counting wrong by at most its area `A / k²` with variance at most a
    /// quarter of that squared. Over the two triangles (`A = ½`) the error
    /// in floor area has a standard deviation of at most
    /// `√((2k − 1) / (2k⁴))`, 0.052 at q = 0.6 (measured: 0.013). A 2 × 2
    /// grid, as many points as an element had before, errs by 0.106.
    #[test]
    fn sunlit_power_is_within_the_grids_error() {
        let dir = tempfile::tempdir().unwrap();
        let grid = Params::new(Quality::new(0.6).unwrap()).direct_grid;
        let sun = Vec3::new(-0.3, 1.0, -0.2).normalize();
        let mut sq = 0.0;
        let n = 16;
        for i in 0..n {
            let (x, z) = (
                0.05 + 0.45 * ((i % 4) as f32 + 0.37) / 4.0,
                0.05 + 0.45 * ((i / 4) as f32 + 0.61) / 4.0,
            );
            let obj = format!(
                "o floor\nv 0 0 0\nv 0 0 1\nv 1 0 1\nv 1 0 0\nf 1 2 3\nf 1 3 4\n\
                 o plate\nv {x} 0.4 {z}\nv {x} 0.4 {z1}\nv {x1} 0.4 {z1}\nv {x1} 0.4 {z}\nf 5 6 7\nf 5 7 8\n",
                x1 = x + 0.3,
                z1 = z + 0.3,
            );
            std::fs::write(dir.path().join("scene.obj"), obj).unwrap();
            let toml = format!(
                "[[materials]]\nname = \"grey\"\ntype = \"diffuse\"\nreflectance = [0.5, 0.5, 0.5]\n\n\
                 [[objects]]\nname = \"floor\"\nmesh = \"scene.obj\"\ngroup = \"floor\"\nmaterial = \"grey\"\n\n\
                 [[objects]]\nname = \"plate\"\nmesh = \"scene.obj\"\ngroup = \"plate\"\nmaterial = \"grey\"\n\n\
                 [[lights]]\ntype = \"sun\"\ndirection = [{}, {}, {}]\nradiance = [1, 1, 1]\nangular_diameter = 0.53\n",
                sun.x, sun.y, sun.z
            );
            std::fs::write(dir.path().join("scene.toml"), toml).unwrap();
            let scene = Scene::load(dir.path().join("scene.toml")).unwrap();
            let poses = scene.at(0.0);
            let s = Simplified::whole(&scene);
            let h = Hierarchy::build(&s, &poses, &[], 0.0);
            let engine = accel::build(Backend::Bvh, &scene.geometry(), &poses).unwrap();
            let floor: Vec<u32> = s
                .patches
                .iter()
                .zip(&h.patch_node)
                .filter(|(p, _)| p.object == 0)
                .map(|(_, &node)| node)
                .collect();
            assert_eq!(floor.len(), 2);
            let (e, rays) = direct(&h, &floor, &scene.lights, engine.as_ref(), grid);
            assert_eq!(rays, (2 * grid * grid) as u64);
            let full = Light::sun_solid_angle(0.53) * sun.y;
            let lit: f32 = e
                .iter()
                .zip(&floor)
                .map(|(e, &i)| e[0].x / full * h.node(i).area)
                .sum();
            sq += f64::from(lit - (1.0 - 0.09)).powi(2);
        }
        let rms = (sq / n as f64).sqrt();
        let k = grid as f64;
        let bound = ((2.0 * k - 1.0) / (2.0 * k.powi(4))).sqrt();
        println!(
            "{grid} x {grid} points: RMS error {rms:.4} of the floor's area (bound {bound:.4})"
        );
        assert!(rms <= bound, "RMS error {rms} above {bound}");
    }
}
