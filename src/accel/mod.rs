//! One interface for ray queries, so that every renderer in the crate runs
//! unchanged on Embree or on the pure-Rust BVH.
//!
//! Geometry is given once as object-space triangle meshes; each mesh is one
//! *instance* whose object-to-world transform can change. Moving to a new
//! scene time therefore only updates transforms (and, for Embree, recommits
//! the top-level scene) instead of rebuilding any triangle hierarchy.

use anyhow::Result;
use glam::{Affine3A, Vec3};

use crate::ray::Ray;
use crate::scene::MeshGeometry;

pub mod bvh;
#[cfg(feature = "embree")]
pub mod embree;

/// The closest intersection of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit, in units of `Ray::dir`.
    pub t: f32,
    /// Index of the mesh (scene object) that was hit.
    pub object: u32,
    /// Index of the triangle within that mesh.
    pub primitive: u32,
    /// Barycentric coordinates of the hit: `p = (1-u-v) v0 + u v1 + v v2`.
    pub u: f32,
    pub v: f32,
    /// World-space geometric normal, normalized, oriented by the triangle's
    /// winding: `(v1 - v0) x (v2 - v0)`.
    pub normal: Vec3,
}

/// Ray queries against a committed scene. Implementations are safe to share
/// between tracing threads.
pub trait RayEngine: Send + Sync {
    /// Short name for reports ("embree", "bvh").
    fn name(&self) -> &'static str;

    /// Which backend this is, to build another engine of the same kind.
    fn backend(&self) -> Backend;

    /// Closest hit along the ray, if any.
    fn intersect(&self, ray: &Ray) -> Option<Hit>;

    /// Whether anything blocks the ray within `[tmin, tmax]`.
    fn occluded(&self, ray: &Ray) -> bool;

    /// Closest hits for many rays; `out.len()` must equal `rays.len()`.
    /// Backends override this where batching is faster (e.g. coherent
    /// primary rays).
    fn intersect_batch(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        assert_eq!(
            rays.len(),
            out.len(),
            "intersect_batch: rays and out differ in length"
        );
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.intersect(r);
        }
    }

    /// Occlusion answers for many rays; `out.len()` must equal `rays.len()`.
    fn occluded_batch(&self, rays: &[Ray], out: &mut [bool]) {
        assert_eq!(
            rays.len(),
            out.len(),
            "occluded_batch: rays and out differ in length"
        );
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.occluded(r);
        }
    }
}

/// A ray engine over instanced meshes whose transforms can be updated.
pub trait InstancedEngine: RayEngine {
    /// Sets every instance's object-to-world transform (one per mesh, in mesh
    /// order) and makes the scene ready for queries again.
    fn set_transforms(&mut self, transforms: &[Affine3A]) -> Result<()>;
}

/// Which ray engine to build.
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    serde::Serialize,
    serde::Deserialize,
    strum::Display,
    strum::EnumString,
    strum::IntoStaticStr,
    strum::VariantArray,
    strum::EnumMessage,
)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum Backend {
    /// Intel Embree 3 (needs the `embree` feature).
    Embree,
    /// Pure-Rust BVH (obvhs).
    Bvh,
}

impl Backend {
    /// The backend used when none is asked for: Embree where it is built in.
    pub fn default_available() -> Self {
        if cfg!(feature = "embree") {
            Backend::Embree
        } else {
            Backend::Bvh
        }
    }

    /// Every backend this build contains.
    pub fn available() -> &'static [Backend] {
        if cfg!(feature = "embree") {
            &[Backend::Embree, Backend::Bvh]
        } else {
            &[Backend::Bvh]
        }
    }
}

/// Builds a ray engine over `meshes`, instance `i` placed by `transforms[i]`.
pub fn build(
    backend: Backend,
    meshes: &[MeshGeometry],
    transforms: &[Affine3A],
) -> Result<Box<dyn InstancedEngine>> {
    anyhow::ensure!(
        meshes.len() == transforms.len(),
        "{} meshes but {} transforms",
        meshes.len(),
        transforms.len()
    );
    match backend {
        Backend::Bvh => Ok(Box::new(bvh::BvhEngine::new(meshes, transforms)?)),
        #[cfg(feature = "embree")]
        Backend::Embree => Ok(Box::new(embree::EmbreeEngine::new(meshes, transforms)?)),
        #[cfg(not(feature = "embree"))]
        Backend::Embree => anyhow::bail!(
            "this build of rangewalk has no Embree backend (built without the `embree` feature); use --backend bvh"
        ),
    }
}
