//! Embree ray engine.
use anyhow::Result;
use glam::Affine3A;

use super::{Hit, InstancedEngine, MeshGeometry, Ray, RayEngine};

pub struct EmbreeEngine {}

impl EmbreeEngine {
    pub fn new(_meshes: &[MeshGeometry], _transforms: &[Affine3A]) -> Result<Self> {
        anyhow::bail!("embree backend not written yet")
    }
}

impl RayEngine for EmbreeEngine {
    fn name(&self) -> &'static str {
        "embree"
    }
    fn intersect(&self, _ray: &Ray) -> Option<Hit> {
        None
    }
    fn occluded(&self, _ray: &Ray) -> bool {
        false
    }
}

impl InstancedEngine for EmbreeEngine {
    fn set_transforms(&mut self, _t: &[Affine3A]) -> Result<()> {
        Ok(())
    }
}
