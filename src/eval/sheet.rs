//! Images side by side in one PNG, at one exposure so that they compare
//! directly: the experiments' strips and the walk's contact sheet.

use std::path::Path;

use anyhow::{Context, Result};
use glam::Vec3;

use super::metrics::luminance;
use crate::image;

/// The exposure (stops) that puts `reference`'s mean luminance at middle
/// grey: images shown at it beside the reference compare directly.
pub fn exposure_for(reference: &[Vec3]) -> f32 {
    let y = reference.iter().map(|&c| luminance(c)).sum::<f64>() / reference.len().max(1) as f64;
    if y > 0.0 {
        (0.18 / y).log2().clamp(-60.0, 60.0) as f32
    } else {
        0.0
    }
}

/// Gap between the images of a strip, in pixels (white).
const STRIP_GAP: u32 = 4;

/// The images (each `w x h` linear radiance) side by side in one PNG, left
/// to right, tone-mapped at one `exposure`.
pub fn write_strip(
    path: impl AsRef<Path>,
    size: (u32, u32),
    images: &[&[Vec3]],
    exposure: f32,
) -> Result<()> {
    write_sheet(path, size, &[images.to_vec()], exposure)
}

/// Rows of images (each `w x h` linear radiance) in one PNG, tone-mapped at
/// one `exposure`; a row shorter than the longest is left white at its end.
pub fn write_sheet(
    path: impl AsRef<Path>,
    size: (u32, u32),
    rows: &[Vec<&[Vec3]>],
    exposure: f32,
) -> Result<()> {
    let tiles: Vec<Vec<Vec<u8>>> = rows
        .iter()
        .map(|row| {
            row.iter()
                .map(|img| image::tonemap_srgb8(img, exposure))
                .collect()
        })
        .collect();
    write_sheet_srgb8(path, size, &tiles)
}

/// Rows of 8-bit sRGB tiles (each `w x h`, `RGBRGB...`) in one PNG, with
/// white gaps between them; a row shorter than the longest is left white
/// at its end.
pub fn write_sheet_srgb8(
    path: impl AsRef<Path>,
    (w, h): (u32, u32),
    rows: &[Vec<Vec<u8>>],
) -> Result<()> {
    let path = path.as_ref();
    let gaps = |n: u32| n.saturating_sub(1) * STRIP_GAP;
    let columns = rows.iter().map(Vec::len).max().unwrap_or(0) as u32;
    let (width, height) = (
        columns * w + gaps(columns),
        rows.len() as u32 * h + gaps(rows.len() as u32),
    );
    let mut rgb = vec![255u8; (width * height * 3) as usize];
    let line = (w * 3) as usize;
    for (r, row) in rows.iter().enumerate() {
        let y0 = r as u32 * (h + STRIP_GAP);
        for (i, tile) in row.iter().enumerate() {
            anyhow::ensure!(
                tile.len() == line * h as usize,
                "writing {}: a tile of {} bytes is not {w}x{h} RGB",
                path.display(),
                tile.len()
            );
            let x0 = i as u32 * (w + STRIP_GAP);
            for y in 0..h {
                let from = y as usize * line;
                let to = (((y0 + y) * width + x0) * 3) as usize;
                rgb[to..to + line].copy_from_slice(&tile[from..from + line]);
            }
        }
    }
    image::png_io::write(path, width, height, &rgb)
        .with_context(|| format!("writing {}", path.display()))
}
