//! Background fill of the pixels no sample reached, as `pinterp -fb`: a
//! hole takes the farther of its candidates, so that the background, not
//! the foreground, spreads into what the bases did not see.

use super::warp::Accum;

/// Fills holes in scan order. A hole's vertical candidate is the farther of
/// the pixel above (possibly filled just before) and the first filled pixel
/// below; its horizontal one the farther of the pixel to the left and the
/// first filled pixel to the right; it takes the farther of the two. A
/// value travels at most `bound` pixels from a projected sample; holes
/// beyond stay empty. Returns the number of pixels filled.
pub fn background(buffer: &mut [Accum], width: u32, height: u32, bound: u16) -> usize {
    let (w, h) = (width as usize, height as usize);
    let mut filled = 0;
    for y in 0..h {
        for x in 0..w {
            let k = y * w + x;
            if !buffer[k].is_empty() {
                continue;
            }
            let mut best: Option<(Accum, u16)> = None;
            let mut offer = |c: Accum, reach: u16| {
                if c.is_empty() || reach > bound {
                    return;
                }
                if best.is_none_or(|(b, _)| c.z > b.z) {
                    best = Some((c, reach));
                }
            };
            if y > 0 {
                let c = buffer[k - w];
                offer(c, c.reach.saturating_add(1));
            }
            if x > 0 {
                let c = buffer[k - 1];
                offer(c, c.reach.saturating_add(1));
            }
            for d in 1..=(bound as usize).min(h - 1 - y) {
                let c = buffer[k + d * w];
                if !c.is_empty() {
                    offer(c, c.reach.saturating_add(d as u16));
                    break;
                }
            }
            for d in 1..=(bound as usize).min(w - 1 - x) {
                let c = buffer[k + d];
                if !c.is_empty() {
                    offer(c, c.reach.saturating_add(d as u16));
                    break;
                }
            }
            if let Some((c, reach)) = best {
                buffer[k] = Accum { reach, ..c };
                filled += 1;
            }
        }
    }
    filled
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(z: f32) -> Accum {
        Accum {
            z,
            w: 1.0,
            radiance: glam::Vec3::splat(z),
            ..Accum::default()
        }
    }

    #[test]
    fn the_farther_neighbour_fills_a_hole_and_the_bound_holds() {
        // A row: near | hole | far. The hole takes the far value.
        let mut row = vec![at(1.0), Accum::default(), at(5.0)];
        assert_eq!(background(&mut row, 3, 1, 4), 1);
        assert_eq!(row[1].z, 5.0);
        // A hole 3 pixels from anything, with a bound of 2: stays empty
        // in the middle, the two ends are reached.
        let mut row = vec![
            at(1.0),
            Accum::default(),
            Accum::default(),
            Accum::default(),
        ];
        let mut row2 = row.clone();
        assert_eq!(background(&mut row, 4, 1, 2), 2);
        assert!(row[3].is_empty());
        assert_eq!(background(&mut row2, 4, 1, 3), 3);
        assert_eq!(row2[3].reach, 3);
    }
}
