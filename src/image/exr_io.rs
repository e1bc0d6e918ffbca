//! OpenEXR through the pure-Rust `exr` crate: the back end of builds without
//! OpenImageIO, and the independent second reader/writer that cross-checks
//! the OpenImageIO files.

use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};
use exr::prelude::*;

use super::planes::{Attr, Plane, Planes};
use super::{write_atomically, RangeImage};
use crate::scene::Texture;

/// Writes `image` as a single-part, ZIP-compressed EXR, atomically.
pub fn write(path: impl AsRef<Path>, image: &RangeImage) -> Result<()> {
    let path = path.as_ref();
    let planes =
        Planes::from_range(image).with_context(|| format!("writing {}", path.display()))?;
    write_atomically(path, |tmp| write_planes(tmp, &planes))
}

/// Reads a range image written by [`write`] or by the OpenImageIO back end.
pub fn read(path: impl AsRef<Path>) -> Result<RangeImage> {
    let path = path.as_ref();
    read_planes(path)?
        .into_range()
        .with_context(|| format!("{}: not a range image", path.display()))
}

fn text(s: &str) -> Text {
    Text::from_slice_unchecked(s.as_bytes())
}

pub(super) fn write_planes(path: &Path, planes: &Planes) -> Result<()> {
    let channels = planes
        .channels
        .iter()
        .map(|(name, plane)| {
            let samples = match plane {
                Plane::F32(v) => FlatSamples::F32(v.clone()),
                Plane::U32(v) => FlatSamples::U32(v.clone()),
            };
            AnyChannel::new(text(name), samples)
        })
        .collect();
    let mut attributes = LayerAttributes::default();
    for (name, attr) in &planes.attributes {
        let value = match attr {
            Attr::Float(x) => AttributeValue::F32(*x),
            Attr::Vector([x, y, z]) => AttributeValue::FloatVec3((*x, *y, *z)),
            Attr::Text(s) => AttributeValue::Text(text(s)),
        };
        attributes.other.insert(text(name), value);
    }
    let layer = Layer::new(
        (planes.width as usize, planes.height as usize),
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels),
    );
    Image::from_layer(layer)
        .write()
        .to_file(path)
        .map_err(|e| anyhow!("{}: cannot write EXR: {e}", path.display()))
}

/// Reads the first layer of any flat EXR: float and half channels as f32,
/// unsigned channels verbatim, and the float, 3-vector and text attributes.
pub(super) fn read_planes(path: &Path) -> Result<Planes> {
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| anyhow!("{}: cannot read EXR: {e}", path.display()))?;
    let layer = image.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    let (Ok(width), Ok(height)) = (u32::try_from(width), u32::try_from(height)) else {
        bail!("{}: EXR size {width}x{height} is too large", path.display());
    };
    let channels = layer
        .channel_data
        .list
        .into_iter()
        .map(|c| {
            let plane = match c.sample_data {
                FlatSamples::U32(v) => Plane::U32(v),
                FlatSamples::F32(v) => Plane::F32(v),
                FlatSamples::F16(v) => Plane::F32(v.into_iter().map(f16::to_f32).collect()),
            };
            (
                String::from_utf8_lossy(c.name.as_slice()).into_owned(),
                plane,
            )
        })
        .collect();
    let attributes = image
        .attributes
        .other
        .into_iter()
        .chain(layer.attributes.other)
        .filter_map(|(name, value)| {
            let attr = match value {
                AttributeValue::F32(x) => Attr::Float(x),
                AttributeValue::FloatVec3((x, y, z)) => Attr::Vector([x, y, z]),
                AttributeValue::Text(s) => {
                    Attr::Text(String::from_utf8_lossy(s.as_slice()).into_owned())
                }
                _ => return None,
            };
            Some((String::from_utf8_lossy(name.as_slice()).into_owned(), attr))
        })
        .collect();
    Ok(Planes {
        width,
        height,
        channels,
        attributes,
    })
}

/// Reads the first layer of any EXR as a linear-RGB texture.
pub fn read_texture(path: impl AsRef<Path>) -> Result<Texture> {
    let path = path.as_ref();
    read_planes(path)?.into_texture(path, false)
}
