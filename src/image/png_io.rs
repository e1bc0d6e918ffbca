//! PNG through the pure-Rust `png` crate: 8-bit previews out, textures in.

use std::fs::File;
use std::io::{BufReader, BufWriter};
use std::path::Path;

use anyhow::{anyhow, ensure, Context, Result};
use glam::Vec3;

use super::color::srgb_decode;
use super::write_atomically;
use super::write_error::describe;
use super::Texture;

/// Writes 8-bit sRGB pixels (`RGBRGB...`, top row first), tagged as sRGB,
/// atomically.
pub fn write(path: impl AsRef<Path>, width: u32, height: u32, rgb: &[u8]) -> Result<()> {
    let path = path.as_ref();
    ensure!(
        rgb.len() == width as usize * height as usize * 3 && !rgb.is_empty(),
        "writing {}: {} bytes do not hold {width}x{height} RGB pixels",
        path.display(),
        rgb.len()
    );
    write_atomically(path, |tmp| {
        let err = |e: png::EncodingError| {
            let why = match &e {
                png::EncodingError::IoError(io) => describe(io),
                e => e.to_string(),
            };
            anyhow!("{}: cannot write PNG: {why}", tmp.display())
        };
        let file = File::create(tmp)
            .map_err(|e| anyhow!("{}: cannot create: {}", tmp.display(), describe(&e)))?;
        let mut encoder = png::Encoder::new(BufWriter::new(file), width, height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        // fdeflate: a walk writes a preview a frame, and the default
        // level took as long as making a frame (a few percent larger files).
        encoder.set_compression(png::Compression::Fast);
        let mut writer = encoder.write_header().map_err(err)?;
        writer.write_image_data(rgb).map_err(err)?;
        writer.finish().map_err(err)
    })
}

/// Reads any PNG as linear RGB. Samples are taken as sRGB-encoded, as PNG
/// textures almost always are; grey is replicated and alpha dropped.
pub fn read(path: impl AsRef<Path>) -> Result<Texture> {
    let path = path.as_ref();
    let err = |e: png::DecodingError| anyhow!("{}: cannot read PNG: {e}", path.display());
    let file = File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
    let mut decoder = png::Decoder::new(BufReader::new(file));
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().map_err(err)?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| anyhow!("{}: PNG is too large", path.display()))?;
    let mut buf = vec![0; size];
    let info = reader.next_frame(&mut buf).map_err(err)?;
    let channels = info.color_type.samples();
    let samples: Vec<f32> = match info.bit_depth {
        png::BitDepth::Sixteen => buf[..info.buffer_size()]
            .chunks_exact(2)
            .map(|b| u16::from_be_bytes([b[0], b[1]]) as f32 / 65535.0)
            .collect(),
        _ => buf[..info.buffer_size()]
            .iter()
            .map(|&b| b as f32 / 255.0)
            .collect(),
    };
    let texels = samples
        .chunks_exact(channels)
        .map(|px| {
            let c = if channels >= 3 {
                Vec3::new(px[0], px[1], px[2])
            } else {
                Vec3::splat(px[0])
            };
            c.map(srgb_decode)
        })
        .collect();
    Ok(Texture {
        source: path.to_path_buf(),
        width: info.width,
        height: info.height,
        texels,
    })
}
