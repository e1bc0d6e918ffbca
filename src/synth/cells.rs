//! What a band of frame pixels holds once its nearest base is projected,
//! summed over cells of 4 × 4 pixels: whether all are covered, the
//! farthest depth, and a box around the points they show. A later base's
//! tile is left out where every pixel it may touch holds a surface nearer
//! than it by the tolerance; tested pixel by pixel, that test read each
//! frame pixel about ten times a frame, and a cell settles sixteen pixels
//! with one test wherever they all pass it.
//!
//! Passes after the first only cover more pixels and bring them nearer
//! (nearest-first blending), so a summary made before them stays true for
//! what they leave: a cell that hides a tile then hides it still.

use glam::Vec3;

/// A cell's side in frame pixels.
pub(super) const CELL: u32 = 4;

/// Relative rounding allowed between a cell's bound and the test of each
/// of its pixels.
const ROUNDING: f32 = 1e-5;

#[derive(Clone, Copy, Debug)]
struct Cell {
    /// Whether every pixel of the cell is covered.
    covered: bool,
    /// The farthest pixel's depth.
    far: f32,
    /// Bounds of the pixels' points `z · d / |d|`, where `d = (f, u, v)` is
    /// the ray through the pixel's centre along the camera's forward, right
    /// and up axes, in frame pixels (pinhole frames only).
    lo: Vec3,
    hi: Vec3,
}

/// A slab of a tile, seen from the frame's camera: the ray through a
/// pixel, `d` as above, reaches the slab's near face at distance
/// `gap · |d| / (normal · d)`, or never where `normal · d ≤ 0`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Facing {
    pub gap: f32,
    pub normal: Vec3,
}

/// The cells of one band, row by row.
#[derive(Default)]
pub(super) struct Cells {
    columns: usize,
    cells: Vec<Cell>,
}

impl Cells {
    /// Summarizes the band whose first row is frame row `y0`, `rows` rows
    /// of a `width × height` frame, with `focal` its pinhole focal length
    /// in pixels; `depth(j)` is band pixel `j`'s depth if it is covered.
    pub fn build(
        &mut self,
        (width, height): (u32, u32),
        (y0, rows): (u32, u32),
        focal: Option<f32>,
        depth: impl Fn(usize) -> Option<f32>,
    ) {
        self.columns = width.div_ceil(CELL) as usize;
        self.cells.clear();
        let (hw, hh) = (0.5 * width as f32, 0.5 * height as f32);
        for cy in 0..rows.div_ceil(CELL) {
            for cx in 0..width.div_ceil(CELL) {
                let mut cell = Cell {
                    covered: true,
                    far: 0.0,
                    lo: Vec3::INFINITY,
                    hi: Vec3::NEG_INFINITY,
                };
                for y in cy * CELL..((cy + 1) * CELL).min(rows) {
                    let v = hh - ((y0 + y) as f32 + 0.5);
                    for x in cx * CELL..((cx + 1) * CELL).min(width) {
                        let Some(z) = depth((y * width + x) as usize) else {
                            cell.covered = false;
                            continue;
                        };
                        cell.far = cell.far.max(z);
                        if let Some(f) = focal {
                            let d = Vec3::new(f, x as f32 + 0.5 - hw, v);
                            let q = d * (z / d.length());
                            cell.lo = cell.lo.min(q);
                            cell.hi = cell.hi.max(q);
                        }
                    }
                }
                self.cells.push(cell);
            }
        }
    }

    /// Whether every pixel of cell `(cx, cy)` (band cells) is covered and
    /// either no farther than `limit` or nearer, by the relative tolerance
    /// `eps`, than every slab's near face along its ray — where that depth
    /// is at most `cap` (a footprint's depth is no longer bounded by its
    /// slab beyond it). `false` says nothing: its pixels must be tested
    /// one by one.
    pub fn hide(
        &self,
        (cx, cy): (u32, u32),
        (limit, cap): (f32, f32),
        eps: f32,
        slabs: &[Facing],
    ) -> bool {
        let c = &self.cells[cy as usize * self.columns + cx as usize];
        if !c.covered {
            return false;
        }
        if c.far <= limit {
            return true;
        }
        if slabs.is_empty() || c.far * (1.0 - eps) > cap {
            return false;
        }
        slabs.iter().all(|s| {
            // normal · q over the box: least and most at its corners.
            let (a, b) = (s.normal * c.lo, s.normal * c.hi);
            let rounding = ROUNDING * (s.normal.abs() * c.lo.abs().max(c.hi.abs())).element_sum();
            let (least, most) = (
                a.min(b).element_sum() - rounding,
                a.max(b).element_sum() + rounding,
            );
            least > 0.0 && most * (1.0 - eps) <= s.gap
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pixel's own test, in f64: covered, and no farther than `limit` or
    /// (within `cap`) nearer than each slab along its ray.
    fn pixel_hidden(
        z: Option<f32>,
        (u, v, f): (f32, f32, f32),
        (limit, cap): (f32, f32),
        eps: f32,
        slabs: &[Facing],
    ) -> bool {
        let Some(z) = z else { return false };
        if z <= limit {
            return true;
        }
        let beat = z as f64 * (1.0 - eps as f64);
        let d = [f as f64, u as f64, v as f64];
        let length = d.iter().map(|c| c * c).sum::<f64>().sqrt();
        beat <= cap as f64
            && !slabs.is_empty()
            && slabs.iter().all(|s| {
                let n = [s.normal.x as f64, s.normal.y as f64, s.normal.z as f64];
                let facing: f64 = n.iter().zip(d).map(|(a, b)| a * b).sum();
                facing > 0.0 && s.gap as f64 * length >= beat * facing
            })
    }

    /// Wherever a cell hides, each of its pixels passes its own test: on
    /// random bands of surfaces at an angle, with holes, and slabs near
    /// and around them.
    #[test]
    fn a_cell_hides_only_where_each_of_its_pixels_is_hidden() {
        let (width, height, y0, rows) = (37u32, 50u32, 16u32, 18u32);
        let f = 40.0;
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut random = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let (mut hidden, mut cells_tested) = (0, 0);
        for _ in 0..300 {
            // A plane's depth along each ray, some pixels left uncovered.
            let normal = Vec3::new(1.0, random() - 0.5, random() - 0.5).normalize();
            let offset = 1.0 + 20.0 * random();
            let holes = random() < 0.3;
            let depth: Vec<Option<f32>> = (0..rows * width)
                .map(|j| {
                    let (x, y) = (j % width, y0 + j / width);
                    let d = Vec3::new(
                        f,
                        x as f32 + 0.5 - 0.5 * width as f32,
                        0.5 * height as f32 - (y as f32 + 0.5),
                    );
                    let z = offset * d.length() / normal.dot(d);
                    (!(holes && random() < 0.02)).then_some(z * (1.0 + 0.01 * random()))
                })
                .collect();
            let mut cells = Cells::default();
            cells.build((width, height), (y0, rows), Some(f), |j| depth[j]);
            let slabs: Vec<Facing> = (0..1 + (random() * 2.0) as usize)
                .map(|_| Facing {
                    gap: offset * (0.9 + 0.2 * random()),
                    normal: (normal + 0.05 * Vec3::new(random(), random(), random())).normalize(),
                })
                .collect();
            let bounds = (offset * (0.5 + random()), offset * (1.0 + 3.0 * random()));
            for cy in 0..rows.div_ceil(CELL) {
                for cx in 0..width.div_ceil(CELL) {
                    cells_tested += 1;
                    if !cells.hide((cx, cy), bounds, 0.02, &slabs) {
                        continue;
                    }
                    hidden += 1;
                    for y in cy * CELL..((cy + 1) * CELL).min(rows) {
                        for x in cx * CELL..((cx + 1) * CELL).min(width) {
                            let (u, v) = (
                                x as f32 + 0.5 - 0.5 * width as f32,
                                0.5 * height as f32 - ((y0 + y) as f32 + 0.5),
                            );
                            assert!(
                                pixel_hidden(
                                    depth[(y * width + x) as usize],
                                    (u, v, f),
                                    bounds,
                                    0.02,
                                    &slabs
                                ),
                                "cell ({cx}, {cy}) hides pixel ({x}, {y}), which is not hidden"
                            );
                        }
                    }
                }
            }
        }
        // Both answers are given often enough to test something.
        assert!(
            hidden > cells_tested / 10 && hidden < cells_tested * 9 / 10,
            "{hidden} of {cells_tested} cells hide"
        );
    }
}
