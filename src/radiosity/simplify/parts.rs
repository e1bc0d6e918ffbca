//! Connected parts of a mesh, so that small primitives (a book among the
//! books, a knob on a chair) can be pruned on their own.

use std::collections::HashMap;

use glam::Vec3;

use crate::scene::Mesh;

/// One vertex per distinct position (OBJ files repeat positions across
/// texture seams), and each input vertex's index among them.
pub fn weld(positions: &[Vec3]) -> (Vec<Vec3>, Vec<u32>) {
    let mut index = HashMap::new();
    let mut verts = Vec::new();
    let remap = positions
        .iter()
        .map(|p| {
            *index
                .entry(p.to_array().map(f32::to_bits))
                .or_insert_with(|| {
                    verts.push(*p);
                    (verts.len() - 1) as u32
                })
        })
        .collect();
    (verts, remap)
}

/// What [`prune_small`] left and took.
pub struct Pruned {
    pub kept: Mesh,
    /// Indices of the removed triangles in the input mesh, ascending.
    pub triangles: Vec<u32>,
    pub area: f32,
    pub parts: usize,
}

/// The mesh without its connected parts of area below `min_area` (parts
/// meet at shared positions).
pub fn prune_small(mesh: &Mesh, min_area: f32) -> Pruned {
    let (verts, remap) = weld(&mesh.positions);
    let mut parent: Vec<u32> = (0..verts.len() as u32).collect();
    fn root(parent: &mut [u32], mut v: u32) -> u32 {
        while parent[v as usize] != v {
            parent[v as usize] = parent[parent[v as usize] as usize];
            v = parent[v as usize];
        }
        v
    }
    for t in &mesh.triangles {
        let r0 = root(&mut parent, remap[t[0] as usize]);
        for &v in &t[1..] {
            let r = root(&mut parent, remap[v as usize]);
            parent[r as usize] = r0;
        }
    }
    let mut part_area: HashMap<u32, f32> = HashMap::new();
    let roots: Vec<u32> = mesh
        .triangles
        .iter()
        .map(|&t| {
            let r = root(&mut parent, remap[t[0] as usize]);
            *part_area.entry(r).or_default() += mesh.triangle_area(t);
            r
        })
        .collect();
    let small = |r: &u32| part_area[r] < min_area;
    // Summed in triangle order: a sum over the map's values would change in
    // its last bits from run to run with the map's random iteration order.
    let pruned_area = mesh
        .triangles
        .iter()
        .zip(&roots)
        .filter(|(_, r)| small(r))
        .fold(0.0, |sum, (&t, _)| sum + mesh.triangle_area(t));
    let parts = part_area.values().filter(|&&a| a < min_area).count();
    let triangles = (0..mesh.triangles.len() as u32)
        .zip(&roots)
        .filter(|(_, r)| small(r))
        .map(|(i, _)| i)
        .collect();
    let kept = Mesh {
        positions: mesh.positions.clone(),
        triangles: mesh
            .triangles
            .iter()
            .zip(&roots)
            .filter(|(_, r)| !small(r))
            .map(|(&t, _)| t)
            .collect(),
        uvs: None,
    };
    Pruned {
        kept,
        triangles,
        area: pruned_area,
        parts,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_joined_by_a_copied_position_stay_together() {
        // Two triangles sharing an edge through copies of its positions,
        // and a separate tiny triangle.
        let p = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::X,
            Vec3::Y,
            Vec3::ONE,
            Vec3::splat(5.0),
            Vec3::new(5.1, 5.0, 5.0),
            Vec3::new(5.0, 5.1, 5.0),
        ];
        let mesh = Mesh {
            positions: p.to_vec(),
            triangles: vec![[0, 1, 2], [3, 5, 4], [6, 7, 8]],
            uvs: None,
        };
        let pruned = prune_small(&mesh, 0.1);
        assert_eq!(pruned.kept.triangles, vec![[0, 1, 2], [3, 5, 4]]);
        assert_eq!(pruned.triangles, vec![2]);
        assert_eq!(pruned.parts, 1);
        assert!((pruned.area - 0.005).abs() < 1e-6);
    }
}
