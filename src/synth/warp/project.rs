//! Base pixels projected into the frame: each sample's point, depth and
//! footprint (the parallelogram to its neighbours' projections, where
//! they lie on its surface), once a frame for each tile.

use glam::{Affine3A, Vec2, Vec3};
use half::{f16, slice::HalfFloatSliceExt};

use super::super::base::{SKY, TILE};
use super::target::Target;
use super::{Blend, Pass, Projected, Twin, WarpSettings, SKY_Z};

/// Longest side (in frame pixels) a splat may stretch to; beyond it a
/// sample covers one pixel.
const MAX_SPLAT: f32 = 64.0;
/// A base pixel projected into the frame, with everything its deposits
/// need that does not depend on the band they land in.
#[derive(Clone, Copy)]
pub(super) struct Splat {
    pub(super) px: Vec2,
    pub(super) z: f32,
    /// How the depth changes across the frame, so that the z-test compares
    /// depths at pixel centres: a surface seen at a grazing angle changes
    /// depth by more than the tolerance within one pixel, and depths taken
    /// where the samples fall would let the nearer part of every pixel win.
    pub(super) grad: Vec2,
    /// The footprint's sides; zero where the sample lands on one pixel.
    pub(super) sides: [Vec2; 2],
    /// The world point at the frame's time (a direction for sky).
    pub(super) point: Vec3,
    /// Radiance (blended with the twin's where it carries it), the weight
    /// in time and the time value it stands for.
    pub(super) radiance: Vec3,
    pub(super) in_time: f32,
    pub(super) alpha: f32,
    pub(super) pixel: u32,
    pub(super) sky: bool,
}

/// Weight of a base pixel that mixes the light of objects that have moved
/// apart: small enough that any other sample outweighs it.
const TORN_WEIGHT: f32 = 1e-3;

/// Whether two motions (none: the object stays) move points alike.
fn same_motion(a: Option<Affine3A>, b: Option<Affine3A>) -> bool {
    let a = a.unwrap_or(Affine3A::IDENTITY);
    let b = b.unwrap_or(Affine3A::IDENTITY);
    a.abs_diff_eq(b, 1e-5 * (1.0 + a.translation.abs().max_element()))
}

/// Which of a base pixel's neighbours along a row or column lie on its
/// surface.
#[derive(Clone, Copy)]
enum Hands {
    Both,
    After,
    Before,
}

/// Projects the tile's pixels (and a ring of their neighbours, which give
/// the footprints' sides) into `out`.
pub(super) fn prepare_tile(
    target: &Target,
    pass: &Pass,
    t: usize,
    settings: &WarpSettings,
    scratch: &mut Vec<Option<Projected>>,
    layers: &mut [Vec<f32>; 2],
    out: &mut Vec<Splat>,
) {
    out.clear();
    let base = pass.base;
    let tile = &base.tiles[t];
    let all_shared = pass.tile_shared(t);
    let (bw, bh) = (base.width(), base.height());
    // The tile's pixels with a ring of their neighbours: a footprint's side
    // comes from the neighbour after the pixel or, where that one lies
    // across a depth break, from the one before it.
    let (xs, ys) = (tile.x0.saturating_sub(1), tile.y0.saturating_sub(1));
    let x_end = (tile.x0 + TILE + 1).min(bw);
    let y_end = (tile.y0 + TILE + 1).min(bh);
    let sw = x_end - xs;
    // A point at the frame's time.
    let moved = |o: u32, p: Vec3| match pass.moves.get(o as usize).and_then(Option::as_ref) {
        Some(m) => m.transform_point3(p),
        None => p,
    };
    scratch.clear();
    for y in ys..y_end {
        for x in xs..x_end {
            let k = (y * bw + x) as usize;
            let p = base.points[k];
            let o = base.object[k];
            let projected = if o == SKY {
                if p == Vec3::ZERO || !settings.sky {
                    None
                } else {
                    target.direction(p).map(|px| Projected {
                        px,
                        z: SKY_Z,
                        object: SKY,
                        primitive: SKY,
                    })
                }
            } else {
                target.point(moved(o, p)).map(|(px, z)| Projected {
                    px,
                    z,
                    object: o,
                    primitive: base.primitive[k],
                })
            };
            scratch.push(projected);
        }
    }
    // The tile's radiance (and the twin's) as f32, converted a row at a
    // time: one call per row lets the half-float conversion use the CPU's
    // vector instructions where it has them.
    let tw = (tile.x0 + TILE).min(bw) - tile.x0;
    let twin = match pass.twin {
        Some(Twin::Carries { base, .. }) => Some(base),
        _ => None,
    };
    let wanted: [Option<&[[f16; 3]]>; 2] = [Some(&base.radiance), twin.map(|b| &b.radiance[..])];
    for (layer, out) in wanted.iter().zip(layers.iter_mut()) {
        let Some(layer) = layer else { continue };
        out.resize((3 * tw * TILE) as usize, 0.0);
        for y in tile.y0..(tile.y0 + TILE).min(bh) {
            let k = (y * bw + tile.x0) as usize;
            let row = 3 * ((y - tile.y0) * tw) as usize;
            layer[k..k + tw as usize]
                .as_flattened()
                .convert_to_f32_slice(&mut out[row..row + 3 * tw as usize]);
        }
    }
    let [rad, twin_rad] = &*layers;
    let layer = |l: &[f32], x: u32, y: u32, scale: f32| {
        let i = 3 * ((y - tile.y0) * tw + (x - tile.x0)) as usize;
        Vec3::from_slice(&l[i..i + 3]) * scale
    };
    let eps = settings.tolerance;
    // Neighbours on one triangle are one plane, however steeply the base
    // saw it; others must agree in depth (pinterp's test).
    let agrees = |a: &Projected, b: &Projected| {
        a.sky() == b.sky()
            && (a.sky()
                || (a.object == b.object
                    && (a.primitive == b.primitive || (a.z - b.z).abs() <= 2.0 * eps * a.z)))
    };
    // A base pixel beside another object's holds some of that object's
    // light (its samples spread over the pixel). Where the two have moved
    // apart since the base's time, that light would be carried to the wrong
    // place, a line along the pixel's object (the short box's lit top drawn
    // across the tall box behind it), so such a pixel only counts where
    // nothing else covers the frame pixel.
    let motion = |o: u32| pass.moves.get(o as usize).copied().flatten();
    let torn = |x: u32, y: u32, o: u32| {
        let own = motion(o);
        [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)]
            .iter()
            .any(|&(dx, dy)| {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                if nx < xs as i64 || ny < ys as i64 || nx >= x_end as i64 || ny >= y_end as i64 {
                    return false;
                }
                let n = scratch[((ny as u32 - ys) * sw + (nx as u32 - xs)) as usize];
                let other = n.map_or(SKY, |n| n.object);
                other != o && !same_motion(own, if other == SKY { None } else { motion(other) })
            })
    };
    for y in tile.y0..(tile.y0 + TILE).min(bh) {
        for x in tile.x0..(tile.x0 + TILE).min(bw) {
            let li = ((y - ys) * sw + (x - xs)) as usize;
            let Some(s) = scratch[li] else { continue };
            let k = (y * bw + x) as usize;
            let shared = all_shared || pass.shared(k);
            if shared && matches!(pass.twin, Some(Twin::CarriedBy(_))) {
                continue;
            }
            // Offset and depth change to an agreeing neighbour, `d` pixels
            // along the base's rows (`row`) or columns, after the pixel or
            // else (negated) before it, and whether the neighbours on both
            // hands agree.
            let neighbour = |row: bool| -> (Option<(Vec2, f32)>, Hands) {
                // The offset to the neighbour `d` pixels on where it agrees;
                // and whether it shows the pixel's object at all.
                let step = |d: i64| -> (Option<(Vec2, f32)>, bool) {
                    let (nx, ny) = if row {
                        (x as i64 + d, y as i64)
                    } else {
                        (x as i64, y as i64 + d)
                    };
                    if nx < xs as i64 || ny < ys as i64 || nx >= x_end as i64 || ny >= y_end as i64
                    {
                        return (None, false);
                    }
                    let Some(n) = scratch[((ny as u32 - ys) * sw + (nx as u32 - xs)) as usize]
                    else {
                        return (None, false);
                    };
                    let offset = ((n.px - s.px) * d as f32, (n.z - s.z) * d as f32);
                    (agrees(&s, &n).then_some(offset), n.object == s.object)
                };
                // Past an edge of its own object (another face of a box)
                // the surface goes on to the edge: only another object's
                // pixel beyond makes the pixel the last of its surface.
                match (step(1), step(-1)) {
                    ((Some(after), _), (Some(_), _) | (None, true)) => (Some(after), Hands::Both),
                    ((Some(after), _), (None, false)) => (Some(after), Hands::After),
                    ((None, true), (before, _)) => (before, Hands::Both),
                    ((None, false), (before, _)) => (before, Hands::Before),
                }
            };
            let ((n1, hands1), (n2, hands2)) = (neighbour(true), neighbour(false));
            let mut centre = s.px;
            let sides = if settings.splat {
                let short = |e: Vec2| e.abs().max_element() <= MAX_SPLAT;
                // A base pixel's own size in the frame, as if it faced the
                // base: how far its surface can reach past its last sample.
                let natural = || {
                    let side = if s.sky() {
                        target.pixel_side(base, base.camera.position + base.points[k], 1.0)
                    } else {
                        target.pixel_side(base, base.points[k], s.z)
                    };
                    side.min(MAX_SPLAT)
                };
                let (e1, e2) = (
                    n1.map(|n| n.0).filter(|e| short(*e)),
                    n2.map(|n| n.0).filter(|e| short(*e)),
                );
                // The footprint is centred on the pixel's projection, so that
                // a base pixel projected into its own camera covers exactly
                // its own pixel. Where only one hand's neighbour agrees, the
                // pixel is the last of its surface: on the other hand its
                // footprint reaches no farther than the base pixel's own
                // size, for a surface the base saw at a grazing angle spans
                // many frame pixels a base pixel, and half of that past its
                // edge would lay it over what lies beyond (a line of the
                // short box's top drawn across the wall behind).
                let mut one_handed = |e: Vec2, hands: Hands| -> Vec2 {
                    let reach = || (0.5 * natural() / e.length().max(1e-6)).min(0.5);
                    // The neighbour is at +e (after) or −e (before); the
                    // footprint spans [−reach, ½] or [−½, reach] of e.
                    let (lo, hi) = match hands {
                        Hands::Both => return e,
                        Hands::After => (-reach(), 0.5),
                        Hands::Before => (-0.5, reach()),
                    };
                    centre += e * (0.5 * (lo + hi));
                    e * (hi - lo)
                };
                // A side with no agreeing neighbour on either hand (a sliver
                // one base pixel wide) is the other side turned a quarter, no
                // longer than the base pixel's own size, or, for a lone
                // pixel, that size: a frame pixel there would widen every
                // thin foreground object over the gaps beside it.
                match (e1, e2) {
                    (Some(a), Some(b)) => [one_handed(a, hands1), one_handed(b, hands2)],
                    (Some(a), None) => {
                        let a = one_handed(a, hands1);
                        [a, a.perp().normalize_or_zero() * a.length().min(natural())]
                    }
                    (None, Some(b)) => {
                        let b = one_handed(b, hands2);
                        [-b.perp().normalize_or_zero() * b.length().min(natural()), b]
                    }
                    (None, None) => {
                        let side = natural();
                        [Vec2::X * side, Vec2::Y * side]
                    }
                }
            } else {
                [Vec2::ZERO; 2]
            };
            let grad = match (n1, n2) {
                (Some((e1, d1)), Some((e2, d2))) if e1.perp_dot(e2).abs() > 1e-6 => {
                    let det = e1.perp_dot(e2);
                    Vec2::new(d1 * e2.y - d2 * e1.y, e1.x * d2 - e2.x * d1) / det
                }
                (Some((e, d)), _) | (None, Some((e, d))) if e.length_squared() > 1e-12 => {
                    e * (d / e.length_squared())
                }
                _ => Vec2::ZERO,
            };
            let mut radiance = layer(rad, x, y, base.scale);
            let (mut in_time, mut alpha) = (pass.weight, pass.alpha);
            if torn(x, y, s.object) {
                in_time *= TORN_WEIGHT;
            }
            if let (
                true,
                Some(Twin::Carries {
                    base: twin,
                    weight,
                    alpha: twin_alpha,
                }),
            ) = (shared, pass.twin)
            {
                // Nearest-first blending keeps the nearer time's value
                // alone, as if the twin's sample had arrived second.
                if settings.blend == Blend::Average {
                    let sum = pass.weight + weight;
                    radiance =
                        (radiance * pass.weight + layer(twin_rad, x, y, twin.scale) * weight) / sum;
                    alpha = (pass.alpha * pass.weight + twin_alpha * weight) / sum;
                    in_time = sum;
                }
            }
            out.push(Splat {
                px: centre,
                z: s.z + grad.dot(centre - s.px),
                grad,
                sides,
                point: if s.sky() {
                    base.points[k]
                } else {
                    moved(s.object, base.points[k])
                },
                radiance,
                in_time,
                alpha,
                pixel: k as u32,
                sky: s.sky(),
            });
        }
    }
}
