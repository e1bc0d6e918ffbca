//! Fewer, larger triangles for objects whose triangles are finer than a
//! patch, with meshoptimizer's edge-collapse simplifier.

use glam::Vec3;
use meshopt::SimplifyOptions;

use super::nondegenerate;
use super::parts::weld;
use crate::scene::Mesh;

/// How far a coarsened mesh's area may stray from the original's, relative.
pub const AREA_TOLERANCE: f32 = 0.05;

/// meshopt's bound on the geometric error of the collapses, relative to a
/// mesh's extent (its largest side). The same at every quality, so that one
/// target always gives one result and a higher quality never keeps fewer
/// triangles.
pub const ERROR: f32 = 0.05;

/// Targets grow by a quarter octave: fine enough not to keep much more than
/// needed, on a fixed grid so that results are monotone in the target.
const STEPS_PER_OCTAVE: f32 = 4.0;

/// The mesh's triangles reduced towards `target`. The simplifier may
/// collapse whole thin parts (a vase, a book) when the target is far below
/// the mesh's count; the target grows until the area is kept within
/// [`AREA_TOLERANCE`]. `None` when only the full mesh does that.
pub fn coarsen(mesh: &Mesh, target: usize) -> Option<Vec<[Vec3; 3]>> {
    // The simplifier follows topology through shared indices: copies of one
    // position (split by texture seams in the OBJ) must become one vertex.
    let (verts, remap) = weld(&mesh.positions);
    let verts: Vec<[f32; 3]> = verts.iter().map(|v| v.to_array()).collect();
    let indices: Vec<u32> = mesh
        .triangles
        .iter()
        .flat_map(|t| t.map(|v| remap[v as usize]))
        .collect();
    let area = mesh.area();
    let mut step = (STEPS_PER_OCTAVE * (target.max(1) as f32).log2()).ceil();
    loop {
        let target = (step / STEPS_PER_OCTAVE).exp2().round() as usize;
        if target >= mesh.triangles.len() {
            return None;
        }
        let out = meshopt::simplify_decoder(
            &indices,
            &verts,
            target * 3,
            ERROR,
            SimplifyOptions::None,
            None,
        );
        let tris: Vec<[Vec3; 3]> = out
            .chunks_exact(3)
            .map(|c| [0, 1, 2].map(|k| Vec3::from_array(verts[c[k] as usize])))
            .filter(nondegenerate)
            .collect();
        let kept: f32 = tris
            .iter()
            .map(|t| 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length())
            .sum();
        if tris.len() < mesh.triangles.len() && (kept - area).abs() <= AREA_TOLERANCE * area {
            return Some(tris);
        }
        step += 1.0;
    }
}
