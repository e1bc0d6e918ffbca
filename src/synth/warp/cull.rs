//! Nearest-first culling: a later base's tile left out where it cannot
//! change the band of the frame it would land in.

use glam::{Affine3A, Vec3};

use super::super::base::Tile;
use super::super::cells::{Cells, Facing, CELL};
use super::target::{Reach, Target};
use super::Hot;

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
pub(super) fn hidden(
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

#[cfg(test)]
mod tests {
    use super::super::Hot;
    use super::*;
    use crate::camera::{Camera, Projection};
    use crate::synth::base::{Bounds, Tile, TILE};
    use crate::synth::cells::Cells;

    /// A floor seen at an angle, 3.3 to 4.2 units away, behind what an
    /// earlier base put at each pixel: its nearest point is nearer than
    /// most of those by far more than the tolerance, so only its slab shows
    /// that it is hidden; where it is nearer than what the pixels hold, it
    /// is not.
    #[test]
    fn a_slab_shows_a_tile_seen_at_an_angle_hidden_where_it_is() {
        use crate::synth::base::Slab;
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
        use crate::synth::base::Slab;
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
        use crate::synth::base::Slab;
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
}
