//! The status lines drawn over the bottom of the frame: where the viewer
//! is, the time, frames per second and the bases in use. A fixed 8 × 8
//! bitmap font keeps them legible at any frame size and the rows they
//! cover known, so the rest of a screenshot is the synthesized frame.

use font8x8::legacy::BASIC_LEGACY;

/// Pixels per text line, the glyph's 8 and a pixel of space above and below.
const LINE: usize = 10;
const GLYPH: usize = 8;
const BACKGROUND: u32 = 0x20_20_20;
const INK: u32 = 0xe8_e8_e8;

/// Rows at the bottom of a frame that `lines` lines of status cover.
pub fn height(lines: usize) -> usize {
    lines * LINE + 2
}

/// Packs 8-bit RGB into the window's `0RGB` pixels.
pub fn pack(rgb: &[u8]) -> Vec<u32> {
    rgb.chunks_exact(3)
        .map(|p| (p[0] as u32) << 16 | (p[1] as u32) << 8 | p[2] as u32)
        .collect()
}

/// The window's `0RGB` pixels as 8-bit RGB.
pub fn unpack(pixels: &[u32]) -> Vec<u8> {
    pixels
        .iter()
        .flat_map(|&p| [(p >> 16) as u8, (p >> 8) as u8, p as u8])
        .collect()
}

/// Draws `lines` over the bottom rows of a `width × height` frame, each
/// cut where the frame ends; a frame lower than the status keeps its top.
pub fn draw(pixels: &mut [u32], width: usize, height: usize, lines: &[String]) {
    let top = height.saturating_sub(self::height(lines.len()));
    for row in pixels[top * width..].chunks_exact_mut(width) {
        row.fill(BACKGROUND);
    }
    for (i, text) in lines.iter().enumerate() {
        let y0 = top + 2 + i * LINE;
        for (c, ch) in text.chars().enumerate() {
            let x0 = 4 + c * GLYPH;
            if x0 + GLYPH > width {
                break;
            }
            let glyph = BASIC_LEGACY
                .get(ch as usize)
                .copied()
                .unwrap_or(BASIC_LEGACY[b'?' as usize]);
            for (dy, bits) in glyph.iter().enumerate() {
                let y = y0 + dy;
                if y >= height {
                    break;
                }
                for dx in 0..GLYPH {
                    if bits >> dx & 1 == 1 {
                        pixels[y * width + x0 + dx] = INK;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_covers_only_the_bottom_rows() {
        let (w, h) = (64, 40);
        let mut px = vec![0x123456u32; w * h];
        draw(&mut px, w, h, &["ab".into(), "|".into()]);
        let top = h - height(2);
        assert!(px[..top * w].iter().all(|&p| p == 0x123456));
        let status = &px[top * w..];
        assert!(status.iter().all(|&p| p == BACKGROUND || p == INK));
        assert!(status.contains(&INK), "text is drawn");
        // `|` is a vertical bar: ink in the second line's glyph column.
        let y = top + 2 + LINE + 1;
        assert!(px[y * w + 4..y * w + 12].contains(&INK));
    }

    #[test]
    fn pack_and_unpack_agree() {
        let rgb = [1u8, 2, 3, 250, 128, 0];
        assert_eq!(pack(&rgb), [0x010203, 0xfa8000]);
        assert_eq!(unpack(&pack(&rgb)), rgb);
    }
}
