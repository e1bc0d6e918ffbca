//! Where direct light is judged from (paper §4.2): one id-image camera per
//! point light, per sample point of an emitting object, and for the sun.
//!
//! The paper treats every light as a point and takes "sample points chosen
//! on area light sources"; an emitter small against the scene gets one (its
//! centroid), a large one a few, one per part of a grid over its extent.
//! Each sample is a 180° fisheye looking out of the emitting side, as the
//! light leaves it (two, back to back, for a two-sided emitter).

use anyhow::Result;
use glam::{Affine3A, Vec3};

use super::idimage::{IdView, Parallel};
use crate::camera::{Camera, Projection};
use crate::scene::{Light, Scene};

/// An emitter whose diagonal exceeds this fraction of the scene's is
/// sampled at more than one point (at most [`MAX_GRID`]² of them).
const LARGE_EMITTER: f32 = 0.25;
const MAX_GRID: usize = 3;
/// Emitter cameras sit this fraction of the scene's diagonal off the
/// surface, on the emitting side, so that their grazing rays do not land
/// on the emitter itself.
const LIFT: f32 = 1e-4;

/// One camera of direct light.
#[derive(Clone, Debug)]
pub struct Probe {
    /// For reports: which light, which sample, which projection.
    pub label: String,
    /// Whether the camera itself moves (a sample of a moving emitter).
    pub moves: bool,
    source: Source,
}

#[derive(Clone, Copy, Debug)]
enum Source {
    /// A sphere camera at a fixed point.
    Point(Vec3),
    Sun(Parallel),
    /// A fisheye riding on `object`, given in its object space, looking
    /// along `normal` from `lift` off the surface.
    Emitter {
        object: usize,
        position: Vec3,
        normal: Vec3,
        lift: f32,
    },
}

impl Probe {
    /// The id-image view of this probe with the scene posed at time `t`.
    pub fn view(&self, scene: &Scene, t: f32, size: u32) -> Result<IdView> {
        match self.source {
            // Same orientation as the base views' spheres.
            Source::Point(p) => Ok(IdView::Camera(super::views::sphere(p, size)?)),
            Source::Sun(par) => Ok(IdView::Parallel(Parallel { size, ..par })),
            Source::Emitter {
                object,
                position,
                normal,
                lift,
            } => {
                let pose = scene.objects[object].motion.pose(t);
                // The image's up turns with the object, so that a rotating
                // emitter's images compare like with like.
                let up = pose.transform_vector3(normal.any_orthonormal_vector());
                let n = pose.transform_vector3(normal).normalize();
                Ok(IdView::Camera(Camera::looking(
                    pose.transform_point3(position) + n * lift,
                    n,
                    up,
                    Projection::Fisheye,
                    size,
                    size,
                )?))
            }
        }
    }
}

/// Every probe of the scene's lights. `bounds` frames the sun: the scene's
/// extent over the whole animation.
pub fn probes(scene: &Scene, bounds: (Vec3, Vec3)) -> Vec<Probe> {
    let (lo, hi) = bounds;
    let diagonal = (hi - lo).length();
    let mut out = Vec::new();
    for (i, light) in scene.lights.iter().enumerate() {
        match *light {
            Light::Point { position, .. } => out.push(Probe {
                label: format!("point light {i} at {position}: sphere"),
                moves: false,
                source: Source::Point(position),
            }),
            Light::Sun { direction, .. } => out.push(Probe {
                label: format!("sun {i} towards {direction}: parallel"),
                moves: false,
                source: Source::Sun(Parallel::new(
                    -direction,
                    (lo + hi) * 0.5,
                    // A hair more than half the diagonal, so that rays
                    // along the framing's edge still clear the scene.
                    0.5 * diagonal * 1.001,
                    1,
                )),
            }),
        }
    }
    for (o, object) in scene.objects.iter().enumerate() {
        let Some(emission) = scene.materials[object.material].emission else {
            continue;
        };
        let pose = object.motion.pose(scene.animation.start);
        for (k, sample) in emitter_samples(&object.mesh, pose, diagonal)
            .into_iter()
            .enumerate()
        {
            // A two-sided emitter lights both half-spaces: a fisheye each.
            let sides: &[f32] = if emission.two_sided {
                &[1.0, -1.0]
            } else {
                &[1.0]
            };
            for &side in sides {
                let normal = sample.normal * side;
                out.push(Probe {
                    label: format!(
                        "emitter `{}` sample {k} at {} facing {} (object space): fisheye",
                        object.name, sample.position, normal
                    ),
                    moves: !object.motion.is_static(),
                    source: Source::Emitter {
                        object: o,
                        position: sample.position,
                        normal,
                        lift: LIFT * diagonal,
                    },
                });
            }
        }
    }
    out
}

struct Sample {
    position: Vec3,
    /// The unit mean winding normal: the emitting side.
    normal: Vec3,
}

/// Area-weighted centroids and mean normals of the emitter's triangles,
/// grouped on a grid over the two longest sides of its bounding box and by
/// the axis direction their normal is closest to. The second grouping gives
/// a closed or curved emitter (whose normals face every way and would
/// average to nothing) one camera per side it faces, each on its surface.
fn emitter_samples(mesh: &crate::scene::Mesh, pose: Affine3A, diagonal: f32) -> Vec<Sample> {
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for &p in &mesh.positions {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let extent = hi - lo;
    let world = pose.transform_vector3(extent).length();
    let grid = ((world / (LARGE_EMITTER * diagonal)).ceil() as usize).clamp(1, MAX_GRID);
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|&a, &b| extent[b].total_cmp(&extent[a]));
    let cell = |c: Vec3, axis: usize| -> usize {
        if extent[axis] <= 0.0 {
            return 0;
        }
        (((c[axis] - lo[axis]) / extent[axis] * grid as f32) as usize).min(grid - 1)
    };
    // Per grid cell and normal direction: area, area-weighted centroid sum,
    // area-weighted normal.
    let mut sums = vec![(0.0f32, Vec3::ZERO, Vec3::ZERO); grid * grid * 6];
    for &[a, b, c] in &mesh.triangles {
        let (a, b, c) = (
            mesh.positions[a as usize],
            mesh.positions[b as usize],
            mesh.positions[c as usize],
        );
        let cross = (b - a).cross(c - a);
        let area = 0.5 * cross.length();
        let centroid = (a + b + c) / 3.0;
        let axis = cross.abs().max_position();
        let facing = 2 * axis + usize::from(cross[axis] < 0.0);
        let s = &mut sums[(cell(centroid, axes[0]) * grid + cell(centroid, axes[1])) * 6 + facing];
        s.0 += area;
        s.1 += centroid * area;
        s.2 += cross * 0.5;
    }
    sums.into_iter()
        .filter(|s| s.0 > 0.0)
        .map(|(area, weighted, normal)| Sample {
            position: weighted / area,
            normal: normal.normalize(),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Mesh;

    fn quad(size: f32) -> Mesh {
        Mesh {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(size, 0.0, 0.0),
                Vec3::new(size, 0.0, size),
                Vec3::new(0.0, 0.0, size),
            ],
            // Winding normal -y: emits downwards.
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            uvs: None,
        }
    }

    #[test]
    fn small_emitter_is_one_point_facing_its_emitting_side() {
        let s = emitter_samples(&quad(1.0), Affine3A::IDENTITY, 100.0);
        assert_eq!(s.len(), 1);
        assert!((s[0].position - Vec3::new(0.5, 0.0, 0.5)).length() < 1e-6);
        assert!((s[0].normal - Vec3::NEG_Y).length() < 1e-6);
    }

    #[test]
    fn large_emitter_gets_several_points() {
        // As large as the scene: the full grid, one point per cell with
        // triangles in it (a two-triangle quad fills two of nine).
        let s = emitter_samples(&quad(10.0), Affine3A::IDENTITY, 10.0);
        assert!(s.len() > 1, "{} samples", s.len());
        let mean = s.iter().map(|s| s.position).sum::<Vec3>() / s.len() as f32;
        assert!((mean - Vec3::new(5.0, 0.0, 5.0)).length() < 1.0, "{mean}");
    }

    #[test]
    fn opposite_sides_are_sampled_apart() {
        let mut m = quad(1.0);
        // The same quad again, wound the other way: a flat closed shell,
        // whose normals would average to nothing.
        m.triangles.extend([[0, 2, 1], [0, 3, 2]]);
        let s = emitter_samples(&m, Affine3A::IDENTITY, 100.0);
        assert_eq!(s.len(), 2);
        let mut normals: Vec<f32> = s.iter().map(|s| s.normal.y).collect();
        normals.sort_by(f32::total_cmp);
        assert_eq!(normals, [-1.0, 1.0]);
    }
}
