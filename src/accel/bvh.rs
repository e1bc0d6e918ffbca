//! Pure-Rust ray engine on obvhs.
use anyhow::Result;
use glam::Affine3A;

use super::{Hit, InstancedEngine, MeshGeometry, Ray, RayEngine};

pub struct BvhEngine {}

impl BvhEngine {
    pub fn new(_meshes: &[MeshGeometry], _transforms: &[Affine3A]) -> Result<Self> {
        anyhow::bail!("bvh backend not written yet")
    }
}

impl RayEngine for BvhEngine {
    fn name(&self) -> &'static str {
        "bvh"
    }
    fn intersect(&self, _ray: &Ray) -> Option<Hit> {
        None
    }
    fn occluded(&self, _ray: &Ray) -> bool {
        false
    }
}

impl InstancedEngine for BvhEngine {
    fn set_transforms(&mut self, _t: &[Affine3A]) -> Result<()> {
        Ok(())
    }
}
