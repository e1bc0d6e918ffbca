//! Radiance `.hdr` (RGBE) pictures in pure Rust: Ward's shared-exponent
//! format, written with the standard per-component run-length scanlines.

use std::fs;
use std::path::Path;

use anyhow::{anyhow, bail, ensure, Context, Result};
use glam::Vec3;

use super::Texture;
use super::{write_atomically, MAX_PIXELS, MAX_SIDE};

// Scanlines of these widths use the "new" run-length encoding; others are
// stored flat, as Radiance does.
const RLE_WIDTHS: std::ops::RangeInclusive<u32> = 8..=0x7fff;
const MIN_RUN: usize = 4;

/// Shared-exponent encoding of one colour; truncates like Radiance's
/// `setcolr`, so a value never decodes brighter than a step above itself.
fn encode(c: Vec3) -> [u8; 4] {
    let c = c.max(Vec3::ZERO).min(Vec3::splat(f32::MAX));
    let max = c.max_element();
    if max.is_nan() || max < 1e-32 {
        return [0; 4];
    }
    // frexp: max = m * 2^e with m in [0.5, 1); `max` is a normal float here.
    let e = ((max.to_bits() >> 23) & 0xff) as i32 - 126;
    if e + 128 > 255 {
        return [255; 4];
    }
    let scale = 2f64.powi(8 - e);
    let byte = |x: f32| ((x as f64 * scale) as u32).min(255) as u8;
    [byte(c.x), byte(c.y), byte(c.z), (e + 128) as u8]
}

/// Decodes to the centre of the quantization step, like Radiance's
/// `colr_color`.
fn decode([r, g, b, e]: [u8; 4]) -> Vec3 {
    if e == 0 {
        return Vec3::ZERO;
    }
    let f = 2f32.powi(e as i32 - (128 + 8));
    Vec3::new(r as f32 + 0.5, g as f32 + 0.5, b as f32 + 0.5) * f
}

/// Writes linear RGB radiance (top row first) as an RGBE picture,
/// atomically. Negative values are clipped to zero, the format has no sign.
pub fn write(path: impl AsRef<Path>, width: u32, height: u32, radiance: &[Vec3]) -> Result<()> {
    let path = path.as_ref();
    ensure!(
        radiance.len() == width as usize * height as usize && !radiance.is_empty(),
        "writing {}: {} pixels do not make a {width}x{height} picture",
        path.display(),
        radiance.len()
    );
    let mut out =
        format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {height} +X {width}\n").into_bytes();
    for row in radiance.chunks_exact(width as usize) {
        let pixels: Vec<[u8; 4]> = row.iter().map(|&c| encode(c)).collect();
        if RLE_WIDTHS.contains(&width) {
            out.extend_from_slice(&[2, 2, (width >> 8) as u8, width as u8]);
            for k in 0..4 {
                let component: Vec<u8> = pixels.iter().map(|p| p[k]).collect();
                run_length(&component, &mut out);
            }
        } else {
            out.extend(pixels.iter().flatten());
        }
    }
    write_atomically(path, |tmp| {
        fs::write(tmp, &out).map_err(|e| {
            anyhow!(
                "{}: cannot write: {}",
                tmp.display(),
                super::write_error::describe(&e)
            )
        })
    })
}

/// Radiance's per-component encoding: `128 + n, byte` for a run of `n`
/// equal bytes, `n, bytes...` for `n <= 128` literal ones.
fn run_length(data: &[u8], out: &mut Vec<u8>) {
    let mut i = 0;
    while i < data.len() {
        let run = data[i..]
            .iter()
            .take(127)
            .take_while(|&&b| b == data[i])
            .count();
        if run >= MIN_RUN {
            out.extend_from_slice(&[128 + run as u8, data[i]]);
            i += run;
            continue;
        }
        // Literal bytes up to the next run worth encoding.
        let mut j = i;
        while j < data.len() && j - i < 128 {
            let ahead = data[j..].iter().take_while(|&&b| b == data[j]).count();
            if ahead >= MIN_RUN {
                break;
            }
            j += 1;
        }
        out.push((j - i) as u8);
        out.extend_from_slice(&data[i..j]);
        i = j;
    }
}

/// Reads an RGBE picture in the standard `-Y h +X w` orientation.
pub fn read(path: impl AsRef<Path>) -> Result<Texture> {
    let path = path.as_ref();
    let bytes = fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let (width, height, texels) = parse(&bytes)
        .with_context(|| format!("{}: not a readable Radiance picture", path.display()))?;
    Ok(Texture {
        source: path.to_path_buf(),
        width,
        height,
        texels,
    })
}

fn parse(bytes: &[u8]) -> Result<(u32, u32, Vec<Vec3>)> {
    let mut lines = bytes.split(|&b| b == b'\n');
    let mut used = 0;
    let mut next_line = || -> Result<&[u8]> {
        let line = lines.next().context("header ends early")?;
        used += line.len() + 1;
        Ok(line)
    };
    ensure!(next_line()?.starts_with(b"#?"), "missing `#?` magic line");
    loop {
        let line = next_line()?;
        if line.is_empty() {
            break;
        }
        if let Some(format) = line.strip_prefix(b"FORMAT=") {
            ensure!(
                format == b"32-bit_rle_rgbe",
                "pixel format `{}` is not RGBE",
                String::from_utf8_lossy(format)
            );
        }
    }
    let size = String::from_utf8_lossy(next_line()?).into_owned();
    let (height, width) = match size.split_whitespace().collect::<Vec<_>>()[..] {
        ["-Y", h, "+X", w] => (h.parse::<u32>(), w.parse::<u32>()),
        _ => bail!("resolution line `{size}` is not `-Y <height> +X <width>`"),
    };
    let (Ok(height), Ok(width)) = (height, width) else {
        bail!("resolution line `{size}` has a bad number");
    };
    ensure!(
        width > 0 && height > 0,
        "picture {width}x{height} has no pixels"
    );
    // A scanline buffer is allocated from the declared width before any
    // pixel arrives: a few header bytes declared 16 GB of it.
    ensure!(
        width <= MAX_SIDE
            && height <= MAX_SIDE
            && u64::from(width) * u64::from(height) <= MAX_PIXELS,
        "picture {width}x{height} is larger than the {MAX_PIXELS} pixels (8192x8192, no side above {MAX_SIDE}) an image may have here"
    );

    let mut data = bytes.get(used..).unwrap_or_default().iter().copied();
    let mut byte = || data.next().context("pixel data ends early");
    let n = width as usize * height as usize;
    let mut texels = Vec::with_capacity(n.min(1 << 24));
    let mut row = vec![[0u8; 4]; width as usize];
    for y in 0..height {
        let first = [byte()?, byte()?, byte()?, byte()?];
        if RLE_WIDTHS.contains(&width) && first[0] == 2 && first[1] == 2 && first[2] < 128 {
            let len = (first[2] as u32) << 8 | first[3] as u32;
            ensure!(
                len == width,
                "scanline {y} has length {len}, expected {width}"
            );
            for k in 0..4 {
                let mut x = 0;
                while x < row.len() {
                    let count = byte()? as usize;
                    let (count, run) = if count > 128 {
                        (count - 128, true)
                    } else {
                        (count, false)
                    };
                    ensure!(
                        count > 0 && x + count <= row.len(),
                        "scanline {y} has a bad run length"
                    );
                    if run {
                        let b = byte()?;
                        row[x..x + count].iter_mut().for_each(|p| p[k] = b);
                    } else {
                        for p in &mut row[x..x + count] {
                            p[k] = byte()?;
                        }
                    }
                    x += count;
                }
            }
        } else {
            row[0] = first;
            for p in &mut row[1..] {
                *p = [byte()?, byte()?, byte()?, byte()?];
            }
        }
        texels.extend(row.iter().map(|&p| decode(p)));
    }
    Ok((width, height, texels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encoding_is_within_one_step() {
        for &v in &[1e-6f32, 0.1, 0.5, 1.0, 1.5, 3.0, 1234.5, 6.0e7] {
            let c = Vec3::new(v, v * 0.5, v * 0.01);
            let back = decode(encode(c));
            // Mantissas have 8 bits against the largest channel.
            let step = v / 128.0;
            assert!((back - c).abs().max_element() <= step, "{c} -> {back}");
        }
        assert_eq!(decode(encode(Vec3::ZERO)), Vec3::ZERO);
        assert_eq!(encode(Vec3::new(-1.0, f32::NAN, 0.0)), [0; 4]);
        // Powers of two sit at mantissa 128.
        assert_eq!(encode(Vec3::splat(1.0)), [128, 128, 128, 129]);
    }

    #[test]
    fn declared_sizes_beyond_the_limits_are_refused_before_allocating() {
        for size in ["-Y 1 +X 4000000000", "-Y 40000 +X 1", "-Y 10000 +X 10000"] {
            let mut file = format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n{size}\n").into_bytes();
            file.extend([1, 1, 1, 128]);
            let e = parse(&file).unwrap_err().to_string();
            assert!(e.contains("larger than"), "{size}: {e}");
        }
    }

    #[test]
    fn run_length_round_trips_runs_and_literals() {
        let mut data = vec![7u8; 300];
        data.extend((0..200).map(|i| (i * 37 % 251) as u8));
        data.extend([1, 1, 1, 2, 2, 2, 2, 2, 3]);
        let mut out = Vec::new();
        run_length(&data, &mut out);
        assert!(out.len() < data.len(), "runs were not compressed");
        let mut decoded = Vec::new();
        let mut it = out.into_iter();
        while let Some(count) = it.next() {
            if count > 128 {
                let b = it.next().unwrap();
                decoded.extend(std::iter::repeat_n(b, count as usize - 128));
            } else {
                decoded.extend(it.by_ref().take(count as usize));
            }
        }
        assert_eq!(decoded, data);
    }
}
