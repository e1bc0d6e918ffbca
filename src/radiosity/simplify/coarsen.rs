//! Fewer, larger triangles for objects whose triangles are finer than a
//! patch, with meshoptimizer's edge-collapse simplifier.

use std::collections::HashMap;

use glam::Vec3;
use meshopt::SimplifyOptions;

use super::nondegenerate;
use crate::scene::Mesh;

/// The mesh's triangles reduced towards `target` (never more than the input),
/// collapsing only while the geometric error stays below `error` times the
/// mesh's extent. Zero-area results are dropped.
pub fn coarsen(mesh: &Mesh, target: usize, error: f32) -> Vec<[Vec3; 3]> {
    // The simplifier follows topology through shared indices: copies of one
    // position (split by texture seams in the OBJ) must become one vertex.
    let mut index = HashMap::new();
    let mut verts: Vec<[f32; 3]> = Vec::new();
    let remap: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            let key = p.to_array().map(f32::to_bits);
            *index.entry(key).or_insert_with(|| {
                verts.push(p.to_array());
                (verts.len() - 1) as u32
            })
        })
        .collect();
    let indices: Vec<u32> = mesh
        .triangles
        .iter()
        .flat_map(|t| t.map(|v| remap[v as usize]))
        .collect();
    let out = meshopt::simplify_decoder(
        &indices,
        &verts,
        target * 3,
        error,
        SimplifyOptions::None,
        None,
    );
    out.chunks_exact(3)
        .map(|c| [0, 1, 2].map(|k| Vec3::from_array(verts[c[k] as usize])))
        .filter(nondegenerate)
        .collect()
}
