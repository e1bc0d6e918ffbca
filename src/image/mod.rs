//! Range images — radiance plus distance, ids and normals per pixel — and
//! their files: OpenEXR (with metadata), Radiance `.hdr` and tone-mapped PNG.

use glam::Vec3;

use crate::camera::Camera;

/// Object/primitive id of a pixel whose ray hit nothing.
pub const NO_HIT: u32 = u32::MAX;

/// Where and when a range image was taken.
#[derive(Clone, Debug, PartialEq)]
pub struct RangeMeta {
    pub camera: Camera,
    /// Scene time (s).
    pub time: f32,
    /// Free-form provenance (scene file, sampler settings).
    pub scene: String,
}

/// A rendered view. Every per-pixel vector is row-major, top row first,
/// `width * height` long. Pixels whose ray hit nothing have distance 0,
/// ids [`NO_HIT`] and a zero normal.
#[derive(Clone, Debug, PartialEq)]
pub struct RangeImage {
    pub width: u32,
    pub height: u32,
    /// Linear RGB radiance.
    pub radiance: Vec<Vec3>,
    /// Distance from the camera position along the pixel's ray to the first hit.
    pub distance: Vec<f32>,
    pub object_id: Vec<u32>,
    pub primitive_id: Vec<u32>,
    /// World-space shading normal at the first hit.
    pub normal: Vec<Vec3>,
    pub meta: RangeMeta,
}

impl RangeImage {
    /// An image with nothing hit and black radiance.
    pub fn empty(meta: RangeMeta) -> Self {
        let (width, height) = (meta.camera.width, meta.camera.height);
        let n = width as usize * height as usize;
        Self {
            width,
            height,
            radiance: vec![Vec3::ZERO; n],
            distance: vec![0.0; n],
            object_id: vec![NO_HIT; n],
            primitive_id: vec![NO_HIT; n],
            normal: vec![Vec3::ZERO; n],
            meta,
        }
    }

    pub fn len(&self) -> usize {
        self.width as usize * self.height as usize
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Reads an image file as a linear RGB texture.
pub fn read_texture(path: &std::path::Path) -> anyhow::Result<crate::scene::Texture> {
    anyhow::bail!("{}: texture reading is not written yet", path.display())
}
