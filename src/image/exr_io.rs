//! OpenEXR through the pure-Rust `exr` crate: the back end of builds without
//! OpenImageIO, and the independent second reader/writer that cross-checks
//! the OpenImageIO files.

use std::path::Path;

use anyhow::{anyhow, bail, ensure, Context, Result};
use exr::prelude::*;

use super::planes::{Attr, DataWindow, Plane, Planes};
use super::Texture;
use super::{write_atomically, RangeImage, MAX_PIXELS};

/// Writes `image` as a single-part, ZIP-compressed EXR, atomically.
pub fn write(path: impl AsRef<Path>, image: &RangeImage) -> Result<()> {
    let path = path.as_ref();
    let planes =
        Planes::from_range(image).with_context(|| format!("writing {}", path.display()))?;
    write_atomically(path, |tmp| write_planes(tmp, planes))
}

/// Reads a range image written by [`write`] or by the OpenImageIO back end.
pub fn read(path: impl AsRef<Path>) -> Result<RangeImage> {
    let path = path.as_ref();
    read_planes(path)?
        .into_range()
        .with_context(|| format!("{}: not a range image", path.display()))
}

/// [`super::read_exr_with_layers_hashed`] through this back end in every
/// build, so that files can be checked (and fuzzed) without OpenImageIO.
pub fn read_with_layers_hashed(
    path: impl AsRef<Path>,
    layers: &[&str],
) -> Result<(RangeImage, Vec<Vec<glam::Vec3>>, u64)> {
    let path = path.as_ref();
    super::gather_layers(path, read_planes(path)?, layers)
}

fn text(s: &str) -> Text {
    Text::from_slice_unchecked(s.as_bytes())
}

/// Takes the planes by value: their samples move into the encoder, so no
/// second copy of the image is made.
pub(super) fn write_planes(path: &Path, planes: Planes) -> Result<()> {
    let channels = planes
        .channels
        .into_iter()
        .map(|(name, plane)| {
            let samples = match plane {
                Plane::F32(v) => FlatSamples::F32(v),
                Plane::U32(v) => FlatSamples::U32(v),
            };
            AnyChannel::new(text(&name), samples)
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
    let mut layer = Layer::new(
        (planes.width as usize, planes.height as usize),
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels),
    );
    // The display window at the origin, the data window inside it.
    let display = match planes.window {
        None => None,
        Some(d) => {
            let (Ok(x), Ok(y), Ok(fw), Ok(fh)) = (
                i32::try_from(d.x),
                i32::try_from(d.y),
                usize::try_from(d.full_width),
                usize::try_from(d.full_height),
            ) else {
                bail!(
                    "{}: window {d:?} does not fit an EXR header",
                    path.display()
                );
            };
            layer.attributes.layer_position = Vec2(x, y);
            Some(IntegerBounds::new(Vec2(0, 0), Vec2(fw, fh)))
        }
    };
    let mut image = Image::from_layer(layer);
    if let Some(display) = display {
        image.attributes.display_window = display;
    }
    image.write().to_file(path).map_err(|e| {
        let why = match &e {
            exr::error::Error::Io(io) => super::write_error::describe(io),
            e => e.to_string(),
        };
        anyhow!("{}: cannot write EXR: {why}", path.display())
    })
}

/// Decoded bytes an EXR may hold per byte of its file. No compression the
/// `exr` crate reads packs more: zlib's limit is 1032:1, and PXR24 keeps
/// 24 of a float's 32 bits before zlib (1376:1), so a header that declares
/// more describes data its file cannot hold.
const MAX_EXPANSION: u64 = 2048;

/// Checks what an EXR header declares before any decoder allocates for
/// it: no layer above [`MAX_PIXELS`], and no more samples than the file's
/// size can hold compressed. A header of a few bytes can declare
/// terabytes, which the decoders allocate up front (found by fuzzing).
pub fn check_header(path: &Path) -> Result<()> {
    let len = std::fs::metadata(path)
        .with_context(|| format!("{}: cannot read EXR", path.display()))?
        .len();
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .map_err(|e| anyhow!("{}: cannot read EXR: {e}", path.display()))?;
    for header in meta.headers.iter() {
        let (w, h) = (header.layer_size.width(), header.layer_size.height());
        let pixels = w as u64 * h as u64;
        ensure!(
            pixels <= MAX_PIXELS,
            "{}: EXR layer of {w}x{h} pixels, more than the {MAX_PIXELS} (8192x8192) an image may hold here",
            path.display()
        );
        // Every sample is decoded to 4 bytes (halves become floats).
        let samples: u64 = header
            .channels
            .list
            .iter()
            .map(|c| pixels / (c.sampling.x().max(1) * c.sampling.y().max(1)) as u64)
            .sum();
        let decoded = 4 * samples;
        ensure!(
            decoded <= MAX_EXPANSION * len + (1 << 20),
            "{}: EXR header declares {w}x{h} pixels in {} channel(s), {decoded} bytes decoded, \
             from a file of {len} bytes, more than any EXR compression holds: the file is damaged",
            path.display(),
            header.channels.list.len()
        );
    }
    Ok(())
}

/// Reads the first layer of any flat EXR: float and half channels as f32,
/// unsigned channels verbatim, and the float, 3-vector and text attributes.
pub(super) fn read_planes(path: &Path) -> Result<Planes> {
    check_header(path)?;
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
    let display = image.attributes.display_window;
    let data = layer.attributes.layer_position;
    let window = (display.position != data || display.size != layer.size).then(|| DataWindow {
        x: i64::from(data.x()) - i64::from(display.position.x()),
        y: i64::from(data.y()) - i64::from(display.position.y()),
        full_width: display.size.width() as u64,
        full_height: display.size.height() as u64,
    });
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
        window,
        channels,
        attributes,
    })
}

/// Reads the first layer of any EXR as a linear-RGB texture.
pub fn read_texture(path: impl AsRef<Path>) -> Result<Texture> {
    let path = path.as_ref();
    read_planes(path)?.into_texture(path, false)
}
