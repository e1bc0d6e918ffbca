//! Pure-Rust ray engine on obvhs, organised like Embree's instancing.
//!
//! Each mesh gets a bottom-level hierarchy (obvhs' PLOC builder, collapsed to
//! its compressed 8-wide layout) in object space, built once. A small top
//! level over the instances' world-space boxes is rebuilt whenever the
//! transforms change, which costs microseconds for the object counts of a
//! scene. A ray entering an instance's box is mapped into object space with
//! the precomputed inverse transform; its direction is mapped too and not
//! renormalized, so object-space `t` equals world-space `t` and hits of
//! different instances compare directly.
//!
//! Triangles are intersected watertight (see [`triangle`]) and nodes with a
//! conservative slab test (see [`node`]), so the engine neither leaks through
//! shared edges nor loses hits at small scene scales.

mod node;
mod triangle;

use std::time::Duration;

use anyhow::{bail, ensure, Result};
use glam::{Affine3A, Mat3A, UVec2, Vec3A};
use obvhs::{
    aabb::Aabb,
    cwbvh::{
        builder::{build_cwbvh, build_cwbvh_from_tris},
        CwBvh, Traversal,
    },
    triangle::Triangle,
    BvhBuildParams,
};
use rayon::prelude::*;

use self::node::{intersect_node, NodeRay};
use self::triangle::ShearedRay;
use super::{Hit, InstancedEngine, RayEngine};
use crate::ray::Ray;
use crate::scene::MeshGeometry;

/// Deepest hierarchy obvhs' fixed traversal stack holds: it keeps one entry
/// per level and silently overwrites the last one when full.
const MAX_DEPTH: usize = 32;

/// Build quality of the per-mesh hierarchies: PLOC with a short search radius
/// and a little reinsertion builds a million triangles in about a second on
/// two cores while tracing close to the slowest presets.
fn blas_params() -> BvhBuildParams {
    BvhBuildParams::fast_build()
}

/// The top level holds few boxes, and entering an instance costs a ray
/// transform and a traversal, so each leaf holds a single instance.
fn tlas_params() -> BvhBuildParams {
    BvhBuildParams {
        max_prims_per_leaf: 1,
        ..BvhBuildParams::fast_build()
    }
}

/// The per-mesh (bottom-level) hierarchy and its triangles, stored in the
/// hierarchy's leaf order so a leaf reads contiguous memory.
struct Blas {
    bvh: CwBvh,
    triangles: Vec<[Vec3A; 3]>,
    /// Index in the mesh of each entry of `triangles`.
    primitive: Vec<u32>,
    bounds: Aabb,
}

impl Blas {
    fn build(index: usize, mesh: &MeshGeometry) -> Result<Option<Blas>> {
        if mesh.triangles.is_empty() {
            return Ok(None);
        }
        let tris: Vec<Triangle> = mesh
            .triangles
            .iter()
            .map(|t| Triangle {
                v0: mesh.positions[t[0] as usize].into(),
                v1: mesh.positions[t[1] as usize].into(),
                v2: mesh.positions[t[2] as usize].into(),
            })
            .collect();
        let bvh = build_cwbvh_from_tris(&tris, blas_params(), &mut Duration::default());
        let depth = depth(&bvh);
        ensure!(
            depth <= MAX_DEPTH,
            "mesh {index}: its hierarchy is {depth} levels deep, more than the {MAX_DEPTH} traversal supports (degenerate geometry?)"
        );
        let triangles = bvh
            .primitive_indices
            .iter()
            .map(|&i| {
                let t = &tris[i as usize];
                [t.v0, t.v1, t.v2]
            })
            .collect();
        let bounds = tris.iter().fold(Aabb::empty(), |b, t| b.union(&t.aabb()));
        Ok(Some(Blas {
            primitive: bvh.primitive_indices.clone(),
            bvh,
            triangles,
            bounds,
        }))
    }
}

/// Levels of inner nodes from the root to the deepest one.
fn depth(bvh: &CwBvh) -> usize {
    let mut deepest = 0;
    let mut pending = Vec::new();
    if !bvh.nodes.is_empty() {
        pending.push((0u32, 1usize));
    }
    while let Some((i, d)) = pending.pop() {
        deepest = deepest.max(d);
        let n = &bvh.nodes[i as usize];
        for child in 0..8 {
            if !n.is_child_empty(child) && !n.is_leaf(child) {
                pending.push((n.child_node_index(child), d + 1));
            }
        }
    }
    deepest
}

/// An instance's transform in the forms tracing needs.
#[derive(Clone, Copy)]
struct Placement {
    world_to_object: Affine3A,
    /// Rays of identity instances (static geometry given in world space)
    /// skip the transform.
    identity: bool,
    /// Maps object-space winding normals to world-space ones: the inverse
    /// transpose, negated for mirroring transforms, since mirroring reverses
    /// the winding of the world-space triangle.
    normal: Mat3A,
}

impl Placement {
    fn new(index: usize, object_to_world: &Affine3A) -> Result<Self> {
        ensure!(
            object_to_world.is_finite(),
            "instance {index}: transform {object_to_world} is not finite"
        );
        let det = object_to_world.matrix3.determinant();
        let world_to_object = object_to_world.inverse();
        if det == 0.0 || !world_to_object.is_finite() {
            bail!("instance {index}: transform is not invertible (determinant {det})");
        }
        Ok(Self {
            world_to_object,
            identity: *object_to_world == Affine3A::IDENTITY,
            normal: world_to_object.matrix3.transpose() * det.signum(),
        })
    }
}

/// The closest hit found so far, in the form traversal updates cheaply.
#[derive(Clone, Copy)]
struct Closest {
    t: f32,
    u: f32,
    v: f32,
    instance: u32,
    slot: u32,
}

const NONE: u32 = u32::MAX;

/// The pure-Rust two-level BVH engine.
pub struct BvhEngine {
    /// One per mesh; `None` for meshes without triangles.
    blas: Vec<Option<Blas>>,
    placements: Vec<Placement>,
    /// Top level over the boxes of instances with triangles; its primitive
    /// indices point into `tlas_instances`.
    tlas: CwBvh,
    tlas_instances: Vec<u32>,
}

impl BvhEngine {
    /// Builds the per-mesh hierarchies (in parallel) and places instance `i`
    /// of mesh `i` by `transforms[i]`.
    pub fn new(meshes: &[MeshGeometry], transforms: &[Affine3A]) -> Result<Self> {
        ensure!(
            meshes.len() == transforms.len(),
            "{} meshes but {} transforms",
            meshes.len(),
            transforms.len()
        );
        for (i, mesh) in meshes.iter().enumerate() {
            validate(i, mesh)?;
        }
        let blas = meshes
            .par_iter()
            .enumerate()
            .map(|(i, m)| Blas::build(i, m))
            .collect::<Result<Vec<_>>>()?;
        let mut engine = Self {
            blas,
            placements: Vec::new(),
            tlas: CwBvh::default(),
            tlas_instances: Vec::new(),
        };
        engine.set_transforms(transforms)?;
        Ok(engine)
    }

    fn trace<const ANY: bool>(&self, ray: &Ray) -> Option<Closest> {
        if self.tlas.nodes.is_empty() {
            return None;
        }
        let origin = Vec3A::from(ray.origin);
        let dir = Vec3A::from(ray.dir);
        let top = NodeRay::new(origin, dir);
        let mut best = Closest {
            t: ray.tmax,
            u: 0.0,
            v: 0.0,
            instance: NONE,
            slot: NONE,
        };
        let mut state = self.tlas.new_traversal(dir);
        // One bottom-level traversal state per ray, re-armed per instance.
        let mut inner = Traversal::default();
        let mut node;
        'done: {
            obvhs::traverse!(
                self.tlas,
                node,
                state,
                intersect_node(node, &top, state.oct_inv4, ray.tmin, best.t),
                {
                    let instance = self.tlas_instances
                        [self.tlas.primitive_indices[state.primitive_id as usize] as usize];
                    if self.trace_instance::<ANY>(
                        instance, origin, dir, ray.tmin, &mut best, &mut inner,
                    ) && ANY
                    {
                        break 'done;
                    }
                }
            );
        }
        (best.instance != NONE).then_some(best)
    }

    /// Traces instance `instance`; returns whether it improved `best`.
    #[inline(always)]
    fn trace_instance<const ANY: bool>(
        &self,
        instance: u32,
        origin: Vec3A,
        dir: Vec3A,
        tmin: f32,
        best: &mut Closest,
        state: &mut Traversal,
    ) -> bool {
        let Some(blas) = &self.blas[instance as usize] else {
            return false;
        };
        let placement = &self.placements[instance as usize];
        let (o, d) = if placement.identity {
            (origin, dir)
        } else {
            let to_object = &placement.world_to_object;
            (
                to_object.transform_point3a(origin),
                to_object.transform_vector3a(dir),
            )
        };
        let node_ray = NodeRay::new(o, d);
        let tri_ray = ShearedRay::new(o, d);
        let mut found = false;
        state.reinit(d);
        let mut node;
        'done: {
            obvhs::traverse!(
                blas.bvh,
                node,
                state,
                intersect_node(node, &node_ray, state.oct_inv4, tmin, best.t),
                {
                    let [v0, v1, v2] = blas.triangles[state.primitive_id as usize];
                    if let Some(h) = tri_ray.intersect(v0, v1, v2, tmin, best.t) {
                        *best = Closest {
                            t: h.t,
                            u: h.u,
                            v: h.v,
                            instance,
                            slot: state.primitive_id,
                        };
                        found = true;
                        if ANY {
                            break 'done;
                        }
                    }
                }
            );
        }
        found
    }

    fn hit(&self, c: &Closest) -> Hit {
        let blas = self.blas[c.instance as usize]
            .as_ref()
            .expect("a hit instance has triangles");
        let [v0, v1, v2] = blas.triangles[c.slot as usize];
        // Scale the edges to unit size first so the cross product neither
        // underflows nor overflows at extreme scene scales.
        let e1 = v1 - v0;
        let e2 = v2 - v0;
        let n = (e1 / e1.abs().max_element()).cross(e2 / e2.abs().max_element());
        let normal = (self.placements[c.instance as usize].normal * n).normalize();
        Hit {
            t: c.t,
            object: c.instance,
            primitive: blas.primitive[c.slot as usize],
            u: c.u,
            v: c.v,
            normal: normal.into(),
        }
    }
}

/// Rejects meshes the hierarchy cannot hold, naming the mesh at fault.
fn validate(index: usize, mesh: &MeshGeometry) -> Result<()> {
    let n = mesh.positions.len();
    for (k, tri) in mesh.triangles.iter().enumerate() {
        if let Some(&bad) = tri.iter().find(|&&i| i as usize >= n) {
            bail!(
                "mesh {index}: triangle {k} refers to vertex {bad}, but the mesh has {n} vertices"
            );
        }
    }
    if let Some((k, p)) = mesh
        .positions
        .iter()
        .enumerate()
        .find(|(_, p)| !p.is_finite())
    {
        bail!("mesh {index}: vertex {k} is not finite ({p})");
    }
    Ok(())
}

/// World-space box of an object-space box, widened by a few ulps so rounding
/// of the corners never culls the instance's surface.
fn world_bounds(bounds: &Aabb, object_to_world: &Affine3A) -> Aabb {
    let mut world = Aabb::empty();
    for corner in 0..8 {
        let pick = |bit: usize, lo: f32, hi: f32| if corner & bit == 0 { lo } else { hi };
        let p = Vec3A::new(
            pick(1, bounds.min.x, bounds.max.x),
            pick(2, bounds.min.y, bounds.max.y),
            pick(4, bounds.min.z, bounds.max.z),
        );
        world.extend(object_to_world.transform_point3a(p));
    }
    let pad = world.min.abs().max(world.max.abs()) * (8.0 * f32::EPSILON);
    Aabb::new(world.min - pad, world.max + pad)
}

impl RayEngine for BvhEngine {
    fn name(&self) -> &'static str {
        "bvh"
    }

    fn backend(&self) -> super::Backend {
        super::Backend::Bvh
    }

    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.trace::<false>(ray).map(|c| self.hit(&c))
    }

    fn occluded(&self, ray: &Ray) -> bool {
        self.trace::<true>(ray).is_some()
    }
}

impl InstancedEngine for BvhEngine {
    fn set_transforms(&mut self, transforms: &[Affine3A]) -> Result<()> {
        ensure!(
            transforms.len() == self.blas.len(),
            "{} transforms for {} instances",
            transforms.len(),
            self.blas.len()
        );
        let placements = transforms
            .iter()
            .enumerate()
            .map(|(i, m)| Placement::new(i, m))
            .collect::<Result<Vec<_>>>()?;
        let (boxes, instances): (Vec<Aabb>, Vec<u32>) = self
            .blas
            .iter()
            .zip(transforms)
            .enumerate()
            .filter_map(|(i, (b, m))| b.as_ref().map(|b| (world_bounds(&b.bounds, m), i as u32)))
            .unzip();
        self.tlas = if boxes.is_empty() {
            CwBvh::default()
        } else {
            build_cwbvh(&boxes, tlas_params(), &mut Duration::default())
        };
        self.tlas_instances = instances;
        self.placements = placements;
        Ok(())
    }
}
