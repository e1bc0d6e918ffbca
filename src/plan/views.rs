//! Base views by adaptive subdivision of the view space (paper §4.1).
//!
//! Corners live on an integer lattice of `2^depth` steps per axis, so a
//! corner shared by neighbouring cells is the same lattice point, and one
//! view, without any tolerance on positions. Cells are tested a level at a
//! time and, within a level, a time at a time: the scene is posed once per
//! time and level, and only the current level's corner images are held.

use std::collections::{BTreeMap, BTreeSet};

use anyhow::{Context, Result};
use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::coverage::coverage;
use super::idimage::{self, fitness, IdImage, IdView};
use super::ViewFitness;
use crate::accel::InstancedEngine;
use crate::camera::{Camera, Projection};
use crate::scene::{Scene, ViewSpace};

/// Deepest subdivision per number of dimensions: the smallest cell has
/// sides of `1 / 2^depth` of the view space's, and the most views are 65
/// on a segment, 17² = 289 on a rectangle and 9³ = 729 in a box.
pub fn max_depth(dimensions: usize) -> u32 {
    match dimensions {
        0 => 0,
        1 => 6,
        2 => 4,
        _ => 3,
    }
}

/// The sphere id-image camera of a base view. Every base view looks the
/// same way, so that pixel `p` of two views shows the same direction.
pub fn sphere(position: Vec3, size: u32) -> Result<Camera> {
    Camera::looking(position, Vec3::Z, Vec3::Y, Projection::Sphere, size, size)
}

/// The fitness test of one cell of the view space.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellTest {
    pub depth: u32,
    /// Indices of its corner views.
    pub corners: Vec<usize>,
    /// The lowest fitness of the corners' id-images over the times tested;
    /// `None` where no test was needed (quality 0, or a cell at the depth
    /// limit, which cannot be split).
    pub fitness: Option<f32>,
    pub split: bool,
}

/// The base views and the tests that chose them.
pub struct Subdivided {
    pub positions: Vec<Vec3>,
    pub cells: Vec<CellTest>,
    pub images: usize,
}

/// The view space as an origin and its non-degenerate axes.
struct Lattice {
    origin: Vec3,
    axes: Vec<Vec3>,
    depth: u32,
}

impl Lattice {
    fn new(space: &ViewSpace) -> Self {
        let (origin, axes) = space.edges();
        let depth = max_depth(axes.len());
        Self {
            origin,
            axes,
            depth,
        }
    }

    fn position(&self, c: [u32; 3]) -> Vec3 {
        let steps = (1u32 << self.depth) as f32;
        self.axes
            .iter()
            .zip(c)
            .fold(self.origin, |p, (&a, k)| p + a * (k as f32 / steps))
    }
}

#[derive(Clone, Copy)]
struct Cell {
    origin: [u32; 3],
    size: u32,
    depth: u32,
}

impl Cell {
    fn corners(&self, dims: usize) -> Vec<[u32; 3]> {
        self.offsets(dims, self.size)
    }

    /// The lattice point halfway along every axis (cells that can be split
    /// have an even side).
    fn centre(&self, dims: usize) -> [u32; 3] {
        let mut c = self.origin;
        for k in c.iter_mut().take(dims) {
            *k += self.size / 2;
        }
        c
    }

    fn children(&self, dims: usize) -> Vec<Cell> {
        let half = self.size / 2;
        self.offsets(dims, half)
            .into_iter()
            .map(|origin| Cell {
                origin,
                size: half,
                depth: self.depth + 1,
            })
            .collect()
    }

    /// `origin + step * bits` for every subset of the axes.
    fn offsets(&self, dims: usize, step: u32) -> Vec<[u32; 3]> {
        (0..1u32 << dims)
            .map(|mask| {
                let mut c = self.origin;
                for (axis, k) in c.iter_mut().enumerate().take(dims) {
                    *k += step * ((mask >> axis) & 1);
                }
                c
            })
            .collect()
    }
}

/// Subdivides `space` from its corners while a cell's fitness is below
/// `q` at any of `times`: the fraction of pixels its corner views agree on
/// ([`ViewFitness::Ids`]), or of the surfaces seen from its centre that
/// every corner sees ([`ViewFitness::Coverage`]).
pub fn subdivide(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    space: &ViewSpace,
    times: &[f32],
    (q, measure): (f32, ViewFitness),
    size: u32,
) -> Result<Subdivided> {
    let lattice = Lattice::new(space);
    let dims = lattice.axes.len();
    let mut index: BTreeMap<[u32; 3], usize> = BTreeMap::new();
    let mut order: Vec<[u32; 3]> = Vec::new();
    let mut register = |c: [u32; 3], index: &mut BTreeMap<[u32; 3], usize>| -> usize {
        *index.entry(c).or_insert_with(|| {
            order.push(c);
            order.len() - 1
        })
    };
    let mut frontier = vec![Cell {
        origin: [0; 3],
        size: 1 << lattice.depth,
        depth: 0,
    }];
    for c in frontier[0].corners(dims) {
        register(c, &mut index);
    }
    let mut cells = Vec::new();
    let mut images = 0;
    while !frontier.is_empty() {
        // Quality 0 accepts any fitness, and a cell at the depth limit
        // cannot be split: neither needs id-images.
        let testable = |c: &Cell| q > 0.0 && c.depth < lattice.depth && dims > 0;
        // The paper's fitness compares the corners' id-images, which
        // neighbouring cells share; coverage looks from each cell's centre.
        let needed: BTreeSet<[u32; 3]> = frontier
            .iter()
            .filter(|c| testable(c))
            .flat_map(|c| match measure {
                ViewFitness::Ids => c.corners(dims),
                ViewFitness::Coverage => vec![c.centre(dims)],
            })
            .collect();
        let mut lowest = vec![1.0f32; frontier.len()];
        if !needed.is_empty() {
            for &t in times {
                engine
                    .set_transforms(&scene.at(t))
                    .with_context(|| format!("posing the scene at t = {t}"))?;
                let mut shot: BTreeMap<[u32; 3], IdImage> = BTreeMap::new();
                if measure == ViewFitness::Ids {
                    for &c in &needed {
                        let camera = sphere(lattice.position(c), size)?;
                        shot.insert(c, idimage::render(&*engine, &IdView::Camera(camera)));
                    }
                }
                images += needed.len();
                for (cell, low) in frontier.iter().zip(lowest.iter_mut()) {
                    if !testable(cell) {
                        continue;
                    }
                    let f = match measure {
                        ViewFitness::Ids => {
                            let set: Vec<&IdImage> =
                                cell.corners(dims).iter().map(|c| &shot[c]).collect();
                            fitness(&set)
                        }
                        ViewFitness::Coverage => {
                            let centre = sphere(lattice.position(cell.centre(dims)), size)?;
                            let corners: Vec<Vec3> = cell
                                .corners(dims)
                                .iter()
                                .map(|&c| lattice.position(c))
                                .collect();
                            coverage(&*engine, &centre, &corners)
                        }
                    };
                    *low = low.min(f);
                }
            }
        }
        let mut next = Vec::new();
        for (cell, low) in frontier.iter().zip(lowest) {
            let tested = testable(cell);
            let split = tested && low < q;
            cells.push(CellTest {
                depth: cell.depth,
                corners: cell.corners(dims).iter().map(|c| index[c]).collect(),
                fitness: tested.then_some(low),
                split,
            });
            if split {
                for child in cell.children(dims) {
                    for c in child.corners(dims) {
                        register(c, &mut index);
                    }
                    next.push(child);
                }
            }
        }
        frontier = next;
    }
    Ok(Subdivided {
        positions: order.iter().map(|&c| lattice.position(c)).collect(),
        cells,
        images,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rectangle_axes_skip_the_zero_extent() {
        let l = Lattice::new(&ViewSpace::Rectangle {
            min: Vec3::new(0.0, 1.0, 0.0),
            max: Vec3::new(4.0, 1.0, 2.0),
        });
        assert_eq!(
            l.axes,
            vec![Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 2.0)]
        );
        let steps = 1 << l.depth;
        assert_eq!(l.position([steps, steps, 0]), Vec3::new(4.0, 1.0, 2.0));
    }

    #[test]
    fn children_share_corners_on_the_lattice() {
        let root = Cell {
            origin: [0; 3],
            size: 8,
            depth: 0,
        };
        let kids = root.children(2);
        assert_eq!(kids.len(), 4);
        let corners: BTreeSet<[u32; 3]> = kids.iter().flat_map(|k| k.corners(2)).collect();
        // A 3 x 3 grid of points, the centre shared by all four children.
        assert_eq!(corners.len(), 9);
        assert!(corners.contains(&[4, 4, 0]));
        assert_eq!(Cell { depth: 0, ..root }.children(3).len(), 8);
        assert_eq!(root.children(1).len(), 2);
    }
}
