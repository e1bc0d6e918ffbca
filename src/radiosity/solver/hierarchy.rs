//! Elements and clusters: the two hierarchies hierarchical radiosity links.
//!
//! Below each patch, surface elements are refined lazily by 4-way midpoint
//! subdivision down to a minimum area. Above the patches, bounding-volume
//! hierarchies group them into clusters, so that refinement can start from
//! one self link of the root instead of linking all pairs of patches:
//! first one per orientation, so that most clusters are flat, then one
//! over those.

use std::collections::BTreeMap;

use glam::{Affine3A, Vec3};

use super::extent::Extent;
use crate::radiosity::formfactor::subdivide;
use crate::radiosity::Simplified;

pub const NONE: u32 = u32::MAX;

/// A surface element (a triangle of one patch) or a cluster of patches.
#[derive(Clone, Debug)]
pub struct Node {
    pub cluster: bool,
    /// A surface element, or a cluster whose surfaces all face `normal`
    /// (a tessellated wall, a shelf's tops): it radiates and receives like
    /// one surface of its area. The first-order directional model the other
    /// clusters use gives a flat emitter three quarters of its intensity
    /// along its normal, which darkened every room lit across its walls.
    pub flat: bool,
    /// Range of `normal · x` over a flat node's corners: one value when
    /// its surfaces share a plane.
    pub plane: [f32; 2],
    /// The patch a surface element belongs to (unused for clusters).
    pub patch: u32,
    /// World-space corners of a surface element.
    pub tri: [Vec3; 3],
    /// Unit front normal of a flat node (zero for other clusters).
    pub normal: Vec3,
    /// Surface area (a cluster's is the sum over its patches).
    pub area: f32,
    /// Where the area lies (for links with a cluster end).
    pub extent: Extent,
    /// Bounding sphere.
    pub center: Vec3,
    pub radius: f32,
    pub parent: u32,
    pub children: Vec<u32>,
}

pub struct Hierarchy {
    pub nodes: Vec<Node>,
    /// The top cluster, or `NONE` for a scene without patches.
    pub root: u32,
    /// Surface node of each patch, `NONE` for patches degenerate in world
    /// space.
    pub patch_node: Vec<u32>,
    /// Diffuse reflectance of each patch.
    pub reflectance: Vec<Vec3>,
    /// Emitted radiosity (π × radiance) of each patch, `[front, back]`.
    pub emission: Vec<[Vec3; 2]>,
    /// Surface elements are not split below this area.
    pub min_area: f32,
    /// The surface nodes under each cluster, as a range of `surfaces`
    /// (depth first, so every cluster's are contiguous), with the running
    /// sum of their areas before each (one more than `surfaces`): a point
    /// on a cluster is found by one search of its range rather than a walk
    /// down its tree, a node at a time, for every shadow ray.
    surfaces: Vec<u32>,
    area_before: Vec<f64>,
    spans: Vec<[u32; 2]>,
}

/// Surfaces whose normals agree to this cosine count as facing one way
/// (about 0.25 degrees; tessellation keeps a plane's normals equal to
/// rounding).
pub const FLAT_COS: f32 = 0.999_99;

/// Normals are binned to 1/NORMAL_BINS per component to find the surfaces
/// that face one way.
const NORMAL_BINS: f32 = 4096.0;

/// Patches per cluster at the bottom of the cluster hierarchy.
const CLUSTER_LEAF: usize = 4;

impl Hierarchy {
    /// The patches of `s` posed by `poses` (one per object) and moved by
    /// `lifts` (one per patch, see `standin`), clustered.
    pub fn build(s: &Simplified, poses: &[Affine3A], lifts: &[Vec3], min_area: f32) -> Hierarchy {
        let mut h = Hierarchy {
            nodes: Vec::with_capacity(2 * s.patches.len()),
            root: NONE,
            patch_node: vec![NONE; s.patches.len()],
            reflectance: s.patches.iter().map(|p| p.reflectance).collect(),
            emission: s
                .patches
                .iter()
                .map(|p| {
                    let e = p.emission * std::f32::consts::PI;
                    [e, if p.two_sided { e } else { Vec3::ZERO }]
                })
                .collect(),
            min_area,
            surfaces: Vec::new(),
            area_before: Vec::new(),
            spans: Vec::new(),
        };
        let mut roots = Vec::with_capacity(s.patches.len());
        for (i, p) in s.patches.iter().enumerate() {
            let xf = poses[p.object as usize];
            let lift = lifts.get(i).copied().unwrap_or(Vec3::ZERO);
            let tri = p.vertices.map(|v| xf.transform_point3(v) + lift);
            let cross = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
            let area = 0.5 * cross.length();
            if !(area > 0.0 && area.is_finite()) {
                continue;
            }
            let node = h.push_surface(i as u32, tri, NONE);
            h.patch_node[i] = node;
            roots.push(node);
        }
        // Surfaces facing one way are clustered among themselves first, so
        // that clusters are flat wherever the scene allows; only above the
        // orientations' trees do directions mix.
        let mut by_normal: BTreeMap<[i32; 3], Vec<u32>> = BTreeMap::new();
        for &i in &roots {
            let n = h.node(i).normal * NORMAL_BINS;
            by_normal
                .entry(n.round().as_ivec3().to_array())
                .or_default()
                .push(i);
        }
        let mut groups: Vec<u32> = by_normal
            .into_values()
            .map(|mut items| match items[..] {
                [one] => one,
                _ => h.cluster(&mut items, NONE),
            })
            .collect();
        h.root = match groups[..] {
            [] => NONE,
            [one] if h.node(one).cluster => one,
            _ => h.cluster(&mut groups, NONE),
        };
        h.spans = vec![[0, 0]; h.nodes.len()];
        if h.root != NONE {
            h.span(h.root);
        }
        h.area_before = std::iter::once(0.0)
            .chain(h.surfaces.iter().scan(0.0f64, |sum, &i| {
                *sum += h.nodes[i as usize].area as f64;
                Some(*sum)
            }))
            .collect();
        h
    }

    /// Lists the surface nodes under cluster tree node `i` and records its
    /// range of them.
    fn span(&mut self, i: u32) {
        let start = self.surfaces.len() as u32;
        if self.nodes[i as usize].cluster {
            for k in 0..self.nodes[i as usize].children.len() {
                self.span(self.nodes[i as usize].children[k]);
            }
        } else {
            self.surfaces.push(i);
        }
        self.spans[i as usize] = [start, self.surfaces.len() as u32];
    }

    /// The surface node under cluster `i` that the fraction `u` of its
    /// area falls in (its surfaces in order), and the fraction of that
    /// node's own area where it falls.
    pub fn surface_at(&self, i: u32, u: f32) -> (u32, f32) {
        let [a, b] = self.spans[i as usize];
        let (a, b) = (a as usize, b as usize);
        let (lo, hi) = (self.area_before[a], self.area_before[b]);
        let target = lo + (hi - lo) * u as f64;
        // The last surface whose running sum before it is at most `target`.
        let k = a + self.area_before[a + 1..b].partition_point(|&s| s <= target);
        let node = self.surfaces[k];
        let own = self.area_before[k + 1] - self.area_before[k];
        let f = if own > 0.0 {
            ((target - self.area_before[k]) / own) as f32
        } else {
            0.0
        };
        (node, f.clamp(0.0, 0.999_999))
    }

    fn push_surface(&mut self, patch: u32, tri: [Vec3; 3], parent: u32) -> u32 {
        let cross = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
        let center = (tri[0] + tri[1] + tri[2]) / 3.0;
        let normal = cross.normalize_or_zero();
        let along = tri.map(|v| normal.dot(v));
        let radius = tri
            .iter()
            .map(|&v| v.distance(center))
            .fold(0.0f32, f32::max);
        self.nodes.push(Node {
            cluster: false,
            flat: true,
            plane: [
                along[0].min(along[1]).min(along[2]),
                along[0].max(along[1]).max(along[2]),
            ],
            patch,
            tri,
            normal,
            area: 0.5 * cross.length(),
            extent: Extent::of_triangle(tri, normal),
            center,
            radius,
            parent,
            children: Vec::new(),
        });
        (self.nodes.len() - 1) as u32
    }

    /// A cluster over `items` (surface nodes, or clusters without a
    /// parent yet), split at the median of the
    /// longest axis of their centroids.
    fn cluster(&mut self, items: &mut [u32], parent: u32) -> u32 {
        let me = self.nodes.len() as u32;
        self.nodes.push(Node {
            cluster: true,
            flat: false,
            plane: [0.0; 2],
            patch: NONE,
            tri: [Vec3::ZERO; 3],
            normal: Vec3::ZERO,
            area: 0.0,
            extent: Extent::default(),
            center: Vec3::ZERO,
            radius: 0.0,
            parent,
            children: Vec::new(),
        });
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let (mut clo, mut chi) = (lo, hi);
        let mut area = 0.0;
        for &i in items.iter() {
            let n = &self.nodes[i as usize];
            if n.cluster {
                lo = lo.min(n.center - Vec3::splat(n.radius));
                hi = hi.max(n.center + Vec3::splat(n.radius));
            } else {
                for v in n.tri {
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            clo = clo.min(n.center);
            chi = chi.max(n.center);
            area += n.area;
        }
        let children = if items.len() <= CLUSTER_LEAF {
            for &i in items.iter() {
                self.nodes[i as usize].parent = me;
            }
            items.to_vec()
        } else {
            let axis = (chi - clo).max_position();
            let mid = items.len() / 2;
            let nodes = &self.nodes;
            items.select_nth_unstable_by(mid, |&a, &b| {
                nodes[a as usize].center[axis].total_cmp(&nodes[b as usize].center[axis])
            });
            let (l, r) = items.split_at_mut(mid);
            vec![self.cluster(l, me), self.cluster(r, me)]
        };
        let first = &self.nodes[children[0] as usize];
        let normal = first.normal;
        let flat = children.iter().all(|&c| {
            let c = &self.nodes[c as usize];
            c.flat && c.normal.dot(normal) >= FLAT_COS
        });
        let plane = children
            .iter()
            .fold([f32::INFINITY, f32::NEG_INFINITY], |r, &c| {
                let p = self.nodes[c as usize].plane;
                [r[0].min(p[0]), r[1].max(p[1])]
            });
        let parts = children.iter().map(|&c| {
            let c = &self.nodes[c as usize];
            (c.area, c.extent)
        });
        let extent = Extent::union(parts, flat.then_some(normal));
        let node = &mut self.nodes[me as usize];
        node.extent = extent;
        if flat {
            node.flat = true;
            node.normal = normal;
            node.plane = plane;
        }
        node.center = 0.5 * (lo + hi);
        node.radius = 0.5 * (hi - lo).length();
        node.area = area;
        node.children = children;
        me
    }

    pub fn node(&self, i: u32) -> &Node {
        &self.nodes[i as usize]
    }

    /// Whether `i` has or may get children.
    pub fn splittable(&self, i: u32) -> bool {
        let n = self.node(i);
        !n.children.is_empty() || (!n.cluster && n.area * 0.25 >= self.min_area)
    }

    /// The children of `i`, subdividing a surface element on first use.
    pub fn split(&mut self, i: u32) -> Vec<u32> {
        let n = &self.nodes[i as usize];
        if !n.children.is_empty() || n.cluster {
            return n.children.clone();
        }
        let (patch, tri) = (n.patch, n.tri);
        let kids: Vec<u32> = subdivide(tri)
            .into_iter()
            .map(|t| self.push_surface(patch, t, i))
            .collect();
        // Keep the parent's normal: rounding in tiny children must not tilt
        // them off the patch's plane.
        let normal = self.nodes[i as usize].normal;
        for &k in &kids {
            self.nodes[k as usize].normal = normal;
        }
        self.nodes[i as usize].children = kids.clone();
        kids
    }

    /// Every node once, parents before children.
    pub fn top_down(&self) -> Vec<u32> {
        let mut order = Vec::with_capacity(self.nodes.len());
        if self.root == NONE {
            return order;
        }
        order.push(self.root);
        let mut i = 0;
        while i < order.len() {
            order.extend_from_slice(&self.nodes[order[i] as usize].children);
            i += 1;
        }
        order
    }

    /// The surface elements without children, in node order.
    pub fn leaves(&self) -> Vec<u32> {
        (0..self.nodes.len() as u32)
            .filter(|&i| {
                let n = self.node(i);
                !n.cluster && n.children.is_empty()
            })
            .collect()
    }

    /// The leaf of patch `p`'s subtree that holds the patch's corner `k`
    /// (child `k` of a subdivision keeps corner `k`).
    pub fn corner_leaf(&self, p: usize, k: usize) -> u32 {
        let mut i = self.patch_node[p];
        if i == NONE {
            return NONE;
        }
        while let Some(&c) = self.node(i).children.get(k) {
            i = c;
        }
        i
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    /// A point on a cluster is on one of its own surfaces, and its surfaces
    /// take fractions of the cluster in proportion to their areas: the
    /// cluster's area sampled evenly lands on each surface as often as its
    /// share, to the spacing of the samples.
    #[test]
    fn points_on_a_cluster_fall_on_its_surfaces_by_area() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-box/scene.toml");
        let scene = Scene::load(std::path::Path::new(path)).unwrap();
        let s = crate::radiosity::Simplified::whole(&scene);
        let h = Hierarchy::build(&s, &scene.at(0.0), &[], 0.0);
        let under = |c: u32| {
            let mut found = Vec::new();
            let mut stack = vec![c];
            while let Some(i) = stack.pop() {
                match h.node(i).cluster {
                    true => stack.extend(&h.node(i).children),
                    false => found.push(i),
                }
            }
            found
        };
        let clusters: Vec<u32> = (0..h.nodes.len() as u32)
            .filter(|&i| h.node(i).cluster)
            .collect();
        assert!(clusters.len() > 3, "{} clusters", clusters.len());
        let n = 20_000;
        for c in clusters {
            let mine = under(c);
            let mut hits = vec![0usize; h.nodes.len()];
            for j in 0..n {
                let (i, f) = h.surface_at(c, (j as f32 + 0.5) / n as f32);
                assert!(mine.contains(&i), "cluster {c}: node {i} is not under it");
                assert!((0.0..1.0).contains(&f), "cluster {c}: fraction {f}");
                hits[i as usize] += 1;
            }
            for &i in &mine {
                let share = h.node(i).area / h.node(c).area;
                let got = hits[i as usize] as f32 / n as f32;
                assert!(
                    (got - share).abs() <= 2.0 / n as f32 + 1e-4,
                    "cluster {c}, surface {i}: {got} of the samples for {share} of the area"
                );
            }
        }
    }
}
