//! Range images — radiance plus distance, ids and normals per pixel — and
//! their files: OpenEXR (with metadata), Radiance `.hdr` and tone-mapped PNG.
//!
//! The functions here use OpenImageIO when the `oiio` feature is on and the
//! pure-Rust back ends ([`exr_io`], [`rgbe`], [`png_io`]) otherwise; those
//! stay public in every build so each file can be cross-checked with a
//! second, independent implementation.
//!
//! A range image is one EXR part with channels `R`, `G`, `B` (radiance),
//! `distance`, `N.x`, `N.y`, `N.z` (all 32-bit float), `object_id` and
//! `primitive_id` (32-bit unsigned), and the camera, projection, scene time
//! and scene string as `rangewalk:*` header attributes; reading it back
//! yields an identical [`RangeImage`].
//!
//! Every write goes to a temporary file beside the target and is renamed
//! into place, so a failed or interrupted write never leaves a partial file
//! under the final name. Every error names the file.

use std::path::Path;

use anyhow::{ensure, Context, Result};
use glam::Vec3;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::output::write_with as write_atomically;

mod color;
pub mod exr_io;
#[cfg(feature = "oiio")]
#[allow(unsafe_code)]
mod oiio;
mod planes;
pub mod planes_file;
pub mod png_io;
pub mod rgbe;
mod texture;
mod write_error;

pub use crate::output::{check_output, check_output_dir, OutputKind};
pub use color::tonemap_srgb8;
pub use texture::Texture;

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
            radiance: filled(Vec3::ZERO, n),
            distance: filled(0.0, n),
            object_id: filled(NO_HIT, n),
            primitive_id: filled(NO_HIT, n),
            normal: filled(Vec3::ZERO, n),
            meta,
        }
    }

    /// [`RangeImage::empty`], or an error saying how much memory it
    /// needs where that cannot be had: for images whose size a user chose.
    pub fn try_empty(meta: RangeMeta) -> Result<Self> {
        let (width, height) = (meta.camera.width, meta.camera.height);
        let n = width as usize * height as usize;
        let per_pixel = 2 * size_of::<Vec3>() + size_of::<f32>() + 2 * size_of::<u32>();
        let what = |plane: &'static str| {
            move || {
                format!(
                    "the {plane} of a {width}x{height} range image ({} in all)",
                    crate::alloc::bytes((n as u64).saturating_mul(per_pixel as u64))
                )
            }
        };
        Ok(Self {
            width,
            height,
            radiance: try_filled(Vec3::ZERO, n, what("radiance"))?,
            distance: try_filled(0.0, n, what("distances"))?,
            object_id: try_filled(NO_HIT, n, what("object ids"))?,
            primitive_id: try_filled(NO_HIT, n, what("primitive ids"))?,
            normal: try_filled(Vec3::ZERO, n, what("normals"))?,
            meta,
        })
    }

    pub fn len(&self) -> usize {
        self.width as usize * self.height as usize
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// `n` copies of `value`, written by every thread: a frame's planes are
/// made anew for each frame, and filling them on one thread took about a
/// millisecond of each 512² frame.
fn filled<T: Copy + Send + Sync>(value: T, n: usize) -> Vec<T> {
    let mut v = Vec::with_capacity(n);
    v.par_extend(rayon::iter::repeat_n(value, n));
    v
}

/// [`filled`], failing as [`crate::alloc::reserve`] does.
fn try_filled<T: Copy + Send + Sync>(
    value: T,
    n: usize,
    what: impl FnOnce() -> String,
) -> Result<Vec<T>> {
    let mut v = Vec::new();
    crate::alloc::reserve(&mut v, n, what)?;
    v.par_extend(rayon::iter::repeat_n(value, n));
    Ok(v)
}

/// The most pixels an image may have: a range image holds about 40 bytes
/// per pixel (radiance, distance, ids, normal) before any layer, so 8192²
/// is some 2.7 GB, and the machines this runs on have a few tens of GB.
pub const MAX_PIXELS: u64 = 8192 * 8192;

/// Parses an image size `<W>x<H>` given on a command line.
/// The widest and tallest image any command or the C ABI makes.
pub const MAX_SIDE: u32 = 32768;

pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let err = || format!("size `{s}` is not <W>x<H> with positive integers, e.g. 512x512");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(err)?;
    let (w, h) = (
        w.trim().parse::<u32>().map_err(|_| err())?,
        h.trim().parse::<u32>().map_err(|_| err())?,
    );
    if w == 0 || h == 0 {
        return Err(err());
    }
    if w > MAX_SIDE || h > MAX_SIDE {
        return Err(format!(
            "size `{s}` has a side above the {MAX_SIDE} pixels a range image may have here"
        ));
    }
    if u64::from(w) * u64::from(h) > MAX_PIXELS {
        return Err(format!(
            "size `{s}` is {} pixels, more than the {MAX_PIXELS} (8192x8192) a range image may hold here \
             (about 40 bytes each)",
            u64::from(w) * u64::from(h)
        ));
    }
    Ok((w, h))
}

/// Writes a range image as OpenEXR (whatever the file's extension).
pub fn write_exr(path: impl AsRef<Path>, image: &RangeImage) -> Result<()> {
    #[cfg(feature = "oiio")]
    {
        let path = path.as_ref();
        let planes = planes::Planes::from_range(image)
            .with_context(|| format!("writing {}", path.display()))?;
        write_atomically(path, |tmp| oiio::write(tmp, oiio::Format::Exr, planes))
    }
    #[cfg(not(feature = "oiio"))]
    exr_io::write(path, image)
}

/// Reads a range image written by [`write_exr`] (by either back end).
pub fn read_exr(path: impl AsRef<Path>) -> Result<RangeImage> {
    #[cfg(feature = "oiio")]
    {
        let path = path.as_ref();
        read_planes(path)?
            .into_range()
            .with_context(|| format!("{}: not a range image", path.display()))
    }
    #[cfg(not(feature = "oiio"))]
    exr_io::read(path)
}

/// Writes a range image with further named RGB layers (channels
/// `<name>.R`, `<name>.G`, `<name>.B`) as OpenEXR; returns the content hash
/// of what it wrote ([`exr_content_hash`] of the file).
pub fn write_exr_with_layers(
    path: impl AsRef<Path>,
    image: &RangeImage,
    layers: &[(&str, &[Vec3])],
) -> Result<u64> {
    let path = path.as_ref();
    let planes = (|| {
        let mut planes = planes::Planes::from_range(image)?;
        for (name, values) in layers {
            planes.push_rgb(name, values)?;
        }
        Ok::<_, anyhow::Error>(planes)
    })()
    .with_context(|| format!("writing {}", path.display()))?;
    let hash = planes.content_hash();
    #[cfg(feature = "oiio")]
    write_atomically(path, |tmp| oiio::write(tmp, oiio::Format::Exr, planes))?;
    #[cfg(not(feature = "oiio"))]
    write_atomically(path, |tmp| exr_io::write_planes(tmp, planes))?;
    Ok(hash)
}

/// A hash of an EXR file's channels and `rangewalk:*` attributes,
/// independent of how the file encodes them (see
/// `Planes::content_hash`); an error where the file cannot be read.
pub fn exr_content_hash(path: impl AsRef<Path>) -> Result<u64> {
    Ok(read_planes(path.as_ref())?.content_hash())
}

fn read_planes(path: &Path) -> Result<planes::Planes> {
    #[cfg(feature = "oiio")]
    {
        // The same limits whichever back end decodes the file.
        exr_io::check_header(path)?;
        oiio::read(path)
    }
    #[cfg(not(feature = "oiio"))]
    exr_io::read_planes(path)
}

/// Reads a range image written by [`write_exr_with_layers`] and the named
/// layers, in the order asked.
pub fn read_exr_with_layers(
    path: impl AsRef<Path>,
    layers: &[&str],
) -> Result<(RangeImage, Vec<Vec<Vec3>>)> {
    let (image, values, _) = read_exr_with_layers_hashed(path, layers)?;
    Ok((image, values))
}

/// [`read_exr_with_layers`], and the content hash of the file as
/// [`exr_content_hash`] gives it, from one decode.
pub fn read_exr_with_layers_hashed(
    path: impl AsRef<Path>,
    layers: &[&str],
) -> Result<(RangeImage, Vec<Vec<Vec3>>, u64)> {
    let path = path.as_ref();
    gather_layers(path, read_planes(path)?, layers)
}

/// The range image, the named layers and the content hash of decoded
/// planes, whichever back end decoded them.
fn gather_layers(
    path: &Path,
    mut planes: planes::Planes,
    layers: &[&str],
) -> Result<(RangeImage, Vec<Vec<Vec3>>, u64)> {
    // The hash is one serial pass over every byte: overlap it with the
    // layers' gathering.
    let (hash, values) = rayon::join(
        || planes.content_hash(),
        || {
            layers
                .iter()
                .map(|name| planes.rgb(name))
                .collect::<Result<Vec<_>>>()
        },
    );
    let values = values.with_context(|| format!("{}: not a base image", path.display()))?;
    planes.keep_range_channels();
    let image = planes
        .into_range()
        .with_context(|| format!("{}: not a range image", path.display()))?;
    Ok((image, values, hash))
}

/// Writes linear RGB radiance (top row first) as a Radiance `.hdr` picture.
pub fn write_hdr(path: impl AsRef<Path>, width: u32, height: u32, radiance: &[Vec3]) -> Result<()> {
    #[cfg(feature = "oiio")]
    {
        let path = path.as_ref();
        let planes = rgb_planes(width, height, radiance)
            .with_context(|| format!("writing {}", path.display()))?;
        write_atomically(path, |tmp| oiio::write(tmp, oiio::Format::Hdr, planes))
    }
    #[cfg(not(feature = "oiio"))]
    rgbe::write(path, width, height, radiance)
}

/// Writes an 8-bit sRGB preview of linear radiance: scaled by `2^exposure`
/// and clipped, see [`tonemap_srgb8`].
pub fn write_png_preview(
    path: impl AsRef<Path>,
    width: u32,
    height: u32,
    radiance: &[Vec3],
    exposure: f32,
) -> Result<()> {
    let path = path.as_ref();
    ensure!(
        radiance.len() == width as usize * height as usize && !radiance.is_empty(),
        "writing {}: {} pixels do not make a {width}x{height} image",
        path.display(),
        radiance.len()
    );
    let rgb = tonemap_srgb8(radiance, exposure);
    #[cfg(feature = "oiio")]
    return write_atomically(path, |tmp| oiio::write_rgb8(tmp, width, height, &rgb));
    #[cfg(not(feature = "oiio"))]
    png_io::write(path, width, height, &rgb)
}

/// Reads an image as a linear-RGB texture: any format OpenImageIO reads when
/// the `oiio` feature is on, else PNG, OpenEXR and Radiance `.hdr` chosen by
/// the file extension. 8- and 16-bit images are taken as sRGB-encoded.
pub fn read_texture(path: impl AsRef<Path>) -> Result<Texture> {
    let path = path.as_ref();
    #[cfg(feature = "oiio")]
    return oiio::read_texture(path);
    #[cfg(not(feature = "oiio"))]
    {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or_default()
            .to_ascii_lowercase();
        match ext.as_str() {
            "png" => png_io::read(path),
            "exr" => exr_io::read_texture(path),
            "hdr" | "pic" | "rgbe" => rgbe::read(path),
            _ => anyhow::bail!(
                "{}: cannot read textures of type `.{ext}` without OpenImageIO \
                 (this build reads .png, .exr and .hdr)",
                path.display()
            ),
        }
    }
}

#[cfg(feature = "oiio")]
fn rgb_planes(width: u32, height: u32, radiance: &[Vec3]) -> Result<planes::Planes> {
    ensure!(
        radiance.len() == width as usize * height as usize && !radiance.is_empty(),
        "{} pixels do not make a {width}x{height} image",
        radiance.len()
    );
    let channel = |name: &str, f: fn(&Vec3) -> f32| {
        (
            name.to_string(),
            planes::Plane::F32(radiance.iter().map(f).collect()),
        )
    };
    Ok(planes::Planes {
        width,
        height,
        window: None,
        channels: vec![
            channel("R", |c| c.x),
            channel("G", |c| c.y),
            channel("B", |c| c.z),
        ],
        attributes: Vec::new(),
    })
}
