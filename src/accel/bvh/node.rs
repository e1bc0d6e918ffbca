//! Ray tests against obvhs' compressed 8-wide nodes, made conservative.
//!
//! obvhs' own node test clamps the entry distance to an absolute `1e-4` and
//! ignores `Ray::tmin`, which loses every hit closer than `1e-4` units: a
//! scene modelled in millimetres-as-metres (or simply scaled by `1e-4`) would
//! vanish. This test honours the ray's own interval instead and widens every
//! slab by a few ulps of the terms that compute it (Ize, "Robust BVH Ray
//! Traversal", JCGT 2013), so rounding never culls a child that the exact
//! slab test would enter.

use glam::{BVec4A, Vec3A, Vec4};
use obvhs::cwbvh::node::CwBvhNode;

/// Relative widening of each slab: four ulps of `f32` covers the two
/// roundings of the reciprocal and the two of `q * a + b`.
const WIDEN: f32 = 4.0 * f32::EPSILON;

/// Smallest direction component used for the reciprocal: a component below it
/// would give an infinite reciprocal and `0 * inf = NaN` in the slab test.
/// The substitute keeps the sign, so slabs the ray runs along still give
/// distances far beyond any scene.
const MIN_COMPONENT: f32 = 1e-20;

/// A ray in the frame of one BVH, with what the node tests need.
#[derive(Clone, Copy, Debug)]
pub struct NodeRay {
    pub origin: Vec3A,
    pub inv_dir: Vec3A,
    /// Per axis, whether the ray goes towards negative coordinates; picks
    /// which quantized bound is the near one.
    neg: [bool; 3],
}

impl NodeRay {
    pub fn new(origin: Vec3A, dir: Vec3A) -> Self {
        let safe = |d: f32| {
            if d.abs() < MIN_COMPONENT {
                MIN_COMPONENT.copysign(d)
            } else {
                d
            }
        };
        let inv_dir = Vec3A::new(1.0 / safe(dir.x), 1.0 / safe(dir.y), 1.0 / safe(dir.z));
        Self {
            origin,
            inv_dir,
            neg: [inv_dir.x < 0.0, inv_dir.y < 0.0, inv_dir.z < 0.0],
        }
    }
}

fn quad(q: &[u8; 8], half: usize) -> Vec4 {
    let o = half * 4;
    Vec4::new(
        q[o] as f32,
        q[o + 1] as f32,
        q[o + 2] as f32,
        q[o + 3] as f32,
    )
}

/// Which children of `node` the ray enters within `[tmin, tmax]`, in the
/// hit-mask layout obvhs' `traverse!` macro expects.
#[inline(always)]
pub fn intersect_node(node: &CwBvhNode, ray: &NodeRay, oct_inv4: u32, tmin: f32, tmax: f32) -> u32 {
    // Child bound q (0..=255) lies at p + q * extent, so its slab distance is
    // q * a + b with a = extent / d and b = (p - o) / d.
    let a = node.compute_extent() * ray.inv_dir;
    let b = (Vec3A::from(node.p) - ray.origin) * ray.inv_dir;
    let slack = (b.abs() + a.abs() * 255.0) * WIDEN;
    let b_near = b - slack;
    let b_far = b + slack;

    let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
    let mut hit_mask = 0u32;
    for half in 0..2 {
        let mut t_enter = Vec4::splat(tmin);
        let mut t_exit = Vec4::splat(tmax);
        let axes: [(&[u8; 8], &[u8; 8]); 3] = [
            (&node.child_min_x, &node.child_max_x),
            (&node.child_min_y, &node.child_max_y),
            (&node.child_min_z, &node.child_max_z),
        ];
        for (axis, (lo, hi)) in axes.into_iter().enumerate() {
            let (near, far) = if ray.neg[axis] { (hi, lo) } else { (lo, hi) };
            t_enter = t_enter.max(quad(near, half) * a[axis] + Vec4::splat(b_near[axis]));
            t_exit = t_exit.min(quad(far, half) * a[axis] + Vec4::splat(b_far[axis]));
        }
        let entered: BVec4A = t_enter.cmple(t_exit);
        let mut mask = entered.bitmask();
        while mask != 0 {
            let j = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let child = half * 4 + j;
            let bits = ((child_bits8 >> (child * 8)) & 0xff) as u32;
            let index = ((bit_index8 >> (child * 8)) & 0xff) as u32;
            hit_mask |= bits << index;
        }
    }
    hit_mask
}
