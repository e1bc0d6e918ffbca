//! Projected samples deposited into a band of the frame's rows: the depth
//! test, the blend and, for footprints, the share of each pixel they
//! cover.

use glam::{Vec2, Vec3};

use super::super::base::SKY;
use super::project::Splat;
use super::target::Target;
use super::{tag, Blend, Filter, Hot, Pass, WarpSettings};

/// Largest weight of a sample, for rays that coincide (pinterp's cap).
const MAX_WEIGHT: f32 = 1000.0;
/// Smallest share of a pixel a footprint's overlap counts for.
const MIN_AREA: f32 = 1e-3;

/// The band of frame rows a task deposits into.
pub(super) struct Band<'a> {
    pub(super) y0: u32,
    pub(super) width: u32,
    pub(super) hot: &'a mut [Hot],
    pub(super) alpha: &'a mut [f32],
    /// Base pixels left out by nearest-first blending.
    pub(super) hidden: usize,
}

impl Band<'_> {
    /// Adds `sample` (of `s`) to pixel `(px, py)` of the band (the caller
    /// keeps to the band), at the depth of `s` at the pixel's centre.
    #[inline(always)]
    fn deposit(
        &mut self,
        s: &Splat,
        sample: &Sample,
        (px, py): (i64, i64),
        area: f32,
        covers: bool,
        settings: &WarpSettings,
    ) {
        let j = ((py as u32 - self.y0) * self.width + px as u32) as usize;
        let centre = Vec2::new(px as f32 + 0.5, py as f32 + 0.5);
        let z = if s.sky {
            s.z
        } else {
            (s.z + s.grad.dot(centre - s.px)).clamp(0.5 * s.z, 2.0 * s.z)
        };
        sample.deposit(
            &mut self.hot[j],
            self.alpha.get_mut(j),
            z,
            area,
            covers,
            settings.tolerance,
            settings.blend,
        );
    }
}

/// Deposits a tile's samples in the band's pixels.
pub(super) fn deposit_splats(
    target: &Target,
    (index, pass): (u32, &Pass),
    splats: &[Splat],
    settings: &WarpSettings,
    band: &mut Band,
) {
    let base = pass.base;
    let fw = target.camera.width;
    let cull = settings.culls();
    // Nearest first, a sample that only overlaps a pixel never changes a
    // covered one, and an uncovered pixel is a hole: only covering
    // deposits count, whatever the filter.
    let filter = match settings.blend {
        Blend::Nearest => Filter::Cover,
        Blend::Average => settings.filter,
    };
    let y0 = band.y0;
    let y1 = y0 + band.hot.len() as u32 / fw;
    let eps = settings.tolerance;
    let cam = target.camera.position;
    // Nearest first, a pixel takes one covering sample's radiance whole:
    // weights by angle, time and area would scale it and divide out again.
    let weighted = settings.blend == Blend::Average;
    let in_band = |px: i64, py: i64| px >= 0 && py >= y0 as i64 && px < fw as i64 && py < y1 as i64;
    for s in splats {
        let [e1, e2] = s.sides;
        // Rows a pixel beyond the footprint's bounds cannot be reached
        // (samples of a tile that other bands share mostly land there).
        let reach = 0.5 * (e1.y.abs() + e2.y.abs()) + 1.0;
        if s.px.y + reach < y0 as f32 || s.px.y - reach > y1 as f32 {
            continue;
        }
        let (fx, fy) = (floor(s.px.x), floor(s.px.y));
        let det = e1.perp_dot(e2);
        let footprint = (det.abs() >= 1e-6).then(|| {
            let extent = e1.abs() + e2.abs();
            let (lo, hi) = (s.px - 0.5 * extent, s.px + 0.5 * extent);
            let (rows, cols) = match filter {
                Filter::Box => (
                    (floor(lo.y).max(y0 as i64), ceil(hi.y).min(y1 as i64) - 1),
                    (floor(lo.x).max(0), ceil(hi.x).min(fw as i64) - 1),
                ),
                // Only pixels whose centres the bounds hold (and the pixel
                // under the sample) can be covered.
                Filter::Cover => (
                    (
                        ceil(lo.y - 0.5).min(fy).max(y0 as i64),
                        floor(hi.y - 0.5).max(fy).min(y1 as i64 - 1),
                    ),
                    (
                        ceil(lo.x - 0.5).min(fx).max(0),
                        floor(hi.x - 0.5).max(fx).min(fw as i64 - 1),
                    ),
                ),
            };
            (e1, e2, det, extent, rows, cols)
        });
        // What lands outside the band (the band's neighbours deposit the
        // tiles they share with it too) costs no more than this.
        match footprint {
            Some((.., (ya, yb), (xa, xb))) if ya > yb || xa > xb => continue,
            None if !in_band(fx, fy) => continue,
            _ => {}
        }
        // Where the pixels it could decide already hold nearer or equal
        // samples of earlier bases, nearest-first blending keeps them: the
        // rest of the sample's work would change nothing.
        let named = tag(
            index,
            if s.sky {
                SKY
            } else {
                base.object[s.pixel as usize]
            },
        );
        if cull && hidden_sample(s, footprint.as_ref(), (fx, fy), band, eps, named) {
            band.hidden += 1;
            continue;
        }
        // Weight: how close the base's ray is to the frame's ray, 1/sin of
        // the angle between them (sky: the same direction), times the
        // weight in time.
        let weight = if !weighted {
            1.0
        } else if s.sky {
            MAX_WEIGHT * s.in_time
        } else {
            let k = s.pixel as usize;
            let (a, b) = (base.points[k] - base.camera.position, s.point - cam);
            let sin2 = a.cross(b).length_squared() / (a.length_squared() * b.length_squared());
            (1.0 / sin2).sqrt().min(MAX_WEIGHT) * s.in_time
        };
        let sample = Sample {
            weight,
            radiance: s.radiance,
            alpha: s.alpha,
            pixel: s.pixel,
            tag: named,
        };
        let mut deposit = |px: i64, py: i64, area: f32, covers: bool| {
            band.deposit(s, &sample, (px, py), area, covers, settings);
        };
        let Some((e1, e2, det, extent, (ya, yb), (xa, xb))) = footprint else {
            deposit(fx, fy, 1.0, true);
            continue;
        };
        let origin = s.px - 0.5 * (e1 + e2);
        // Area weights: each frame pixel averages the base pixels over it
        // by how much of it they cover (a box filter of the base's pixels,
        // as the reference's pixels integrate the scene), not by whose
        // centres fall in it, which shifts edges by up to half a pixel. The
        // overlap is that of an axis-aligned box with the footprint's area
        // and the proportions of its bounds (not needed nearest first).
        let area_box = weighted.then(|| {
            let half = 0.5 * extent * (det.abs() / (extent.x * extent.y)).sqrt();
            (s.px - half, s.px + half)
        });
        let overlap = |p: i64, l: f32, h: f32| (h.min(p as f32 + 1.0) - l.max(p as f32)).max(0.0);
        let inv = 1.0 / det;
        for py in ya..=yb {
            let oy = area_box.map(|(bl, bh)| overlap(py, bl.y, bh.y));
            for px in xa..=xb {
                let c = Vec2::new(px as f32 + 0.5, py as f32 + 0.5) - origin;
                // Parallelogram coordinates, half-open so that each pixel
                // centre is covered by one footprint of a surface.
                let a = c.perp_dot(e2) * inv;
                let b = e1.perp_dot(c) * inv;
                // The pixel under the sample has it whole where the
                // footprint is smaller than a pixel.
                let covers =
                    (0.0..1.0).contains(&a) && (0.0..1.0).contains(&b) || (px, py) == (fx, fy);
                let area = match (area_box, oy) {
                    (Some((bl, bh)), Some(oy)) => oy * overlap(px, bl.x, bh.x),
                    _ => 1.0,
                };
                // Slivers below the rounding of positions are no overlap; a
                // covering footprint's sample counts even where the box
                // approximating it misses the pixel.
                if covers {
                    deposit(px, py, area.max(MIN_AREA), true);
                } else if filter == Filter::Box && area > MIN_AREA {
                    deposit(px, py, area, false);
                }
            }
        }
    }
}

/// Whether a sample's covering deposits (the pixels whose centres its
/// footprint's bounds hold, and the pixel under it, both in the band) would
/// all meet pixels of the band covered by samples it is not nearer than (by
/// the tolerance, where they show its object, `tag`'s): under nearest-first
/// blending it then
/// changes nothing (overlapping deposits never change a covered pixel).
/// Its depth over the footprint is bounded by the footprint's corners,
/// between which the depth is linear.
fn hidden_sample(
    s: &Splat,
    footprint: Option<&Footprint>,
    (fx, fy): (i64, i64),
    band: &Band,
    eps: f32,
    tag: u32,
) -> bool {
    let clamp = |z: f32| {
        if s.sky {
            s.z
        } else {
            z.clamp(0.5 * s.z, 2.0 * s.z)
        }
    };
    let at = |c: Vec2| clamp(s.z + s.grad.dot(c - s.px));
    let centre = |px: i64, py: i64| Vec2::new(px as f32 + 0.5, py as f32 + 0.5);
    // Under nearest-first blending a footprint's rows and columns are
    // those of the covering filter, clipped to the band.
    let (mut low, rows, cols) = match footprint {
        None => (at(centre(fx, fy)), (fy, fy), (fx, fx)),
        Some(&(e1, e2, _, _, rows, cols)) => {
            // The depth is linear over the footprint, least at a corner.
            let (g1, g2) = (s.grad.dot(e1), s.grad.dot(e2));
            let corner = s.z - 0.5 * (g1 + g2) + g1.min(0.0) + g2.min(0.0);
            (at(centre(fx, fy)).min(clamp(corner)), rows, cols)
        }
    };
    // Rounding of the depths at pixel centres against the corners'.
    low *= 1.0 - 1e-5;
    (rows.0..=rows.1).all(|py| {
        let row = (py - band.y0 as i64) as usize * band.width as usize;
        band.hot[row + cols.0 as usize..=row + cols.1 as usize]
            .iter()
            .all(|a| a.covered() && low >= a.z * if a.same_object(tag) { 1.0 - eps } else { 1.0 })
    })
}

/// A sample's footprint: its sides, their cross product, its bounds'
/// extent, and the rows and columns its deposits reach.
type Footprint = (Vec2, Vec2, f32, Vec2, (i64, i64), (i64, i64));

/// `⌊x⌋` without a call into libm (x86-64's baseline has no rounding
/// instruction), for the positions of splats, which are far inside `i64`.
#[inline]
pub(super) fn floor(x: f32) -> i64 {
    let i = x as i64;
    i - ((i as f32) > x) as i64
}

#[inline]
pub(super) fn ceil(x: f32) -> i64 {
    let i = x as i64;
    i + ((i as f32) < x) as i64
}

/// One base pixel's contribution.
struct Sample {
    weight: f32,
    radiance: Vec3,
    alpha: f32,
    /// The base pixel, and its pass and object, as [`Hot`] names them.
    pixel: u32,
    tag: u32,
}

impl Sample {
    /// Adds the sample, weighted by the share `area` of the pixel its
    /// footprint overlaps (and its `alpha` to the pixel's sum, where one is
    /// kept). A sample whose footprint `covers` the pixel's centre replaces
    /// what only overlapping samples put there unless it agrees with it in
    /// depth; one that merely overlaps never displaces a covering one (so
    /// foreground edges do not spill over the background) and joins it
    /// only within the tolerance.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn deposit(
        &self,
        a: &mut Hot,
        alpha: Option<&mut f32>,
        z: f32,
        area: f32,
        covers: bool,
        eps: f32,
        blend: Blend,
    ) {
        let w = self.weight * area;
        // Samples of one object within the tolerance are one surface; of
        // two objects (a box standing on the floor, close in depth along
        // the line where they meet) the nearer one is in front.
        let same = a.same_object(self.tag);
        let nearer = z < if same { a.z * (1.0 - eps) } else { a.z };
        let within = same && !nearer && z <= a.z * (1.0 + eps);
        let replace = a.z == 0.0
            || match (covers, a.covered()) {
                // Nearest first, a covering sample still decides a pixel
                // that only the edges of others overlapped.
                (true, false) => !within || blend == Blend::Nearest,
                (false, true) => false,
                _ => nearer,
            };
        if replace {
            *a = Hot {
                z,
                w,
                radiance: self.radiance * w,
                best: w,
                pixel: self.pixel,
                tag: self.tag | covers as u32,
            };
            if let Some(alpha) = alpha {
                *alpha = self.alpha * w;
            }
        } else if within && blend == Blend::Average {
            a.w += w;
            a.radiance += self.radiance * w;
            if let Some(alpha) = alpha {
                *alpha += self.alpha * w;
            }
            a.z = a.z.min(z);
            a.tag |= covers as u32;
            if w > a.best {
                a.best = w;
                a.pixel = self.pixel;
                a.tag = self.tag | (a.tag & 1);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_and_ceil_agree_with_libm() {
        for x in [
            -2.5f32, -2.0, -0.5, -0.0, 0.0, 0.3, 1.0, 1.7, 511.99, 512.0, -1e-7, 1e-7,
        ] {
            assert_eq!(floor(x), x.floor() as i64, "floor {x}");
            assert_eq!(ceil(x), x.ceil() as i64, "ceil {x}");
        }
    }
}
