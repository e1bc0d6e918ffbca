//! Form factors: point-to-polygon analytic, visibility by shadow rays.
//!
//! The differential form factor from a point to a polygon has a closed form
//! (Lambert; Nishita & Nakamae): `F = 1/(2π) Σ_k γ_k (n · ĝ_k)`, with `γ_k`
//! the angle the k-th edge subtends at the point and `ĝ_k` the unit normal
//! of the plane through the point and that edge. It stays finite for
//! touching and adjacent polygons, where the centroid-to-centroid `1/r²`
//! kernel blows up. The polygon must lie in the point's upper half-space,
//! so sources are clipped to it first; area averages over a receiver come
//! from the point formula at interior points of its midpoint subdivision.

use std::f32::consts::{FRAC_PI_2, PI};

use glam::{BVec4A, Vec3, Vec4};

/// A convex polygon of at most four corners: a triangle clipped by one
/// plane.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Polygon {
    corners: [Vec3; 4],
    len: usize,
}

impl Polygon {
    pub fn triangle(t: [Vec3; 3]) -> Self {
        Self {
            corners: [t[0], t[1], t[2], Vec3::ZERO],
            len: 3,
        }
    }

    pub fn corners(&self) -> &[Vec3] {
        &self.corners[..self.len]
    }

    /// The part of the polygon where `(p - x) · n >= 0`.
    pub fn clip_above(&self, x: Vec3, n: Vec3) -> Polygon {
        let mut out = Polygon::default();
        let c = self.corners();
        for i in 0..c.len() {
            let (a, b) = (c[i], c[(i + 1) % c.len()]);
            let (da, db) = ((a - x).dot(n), (b - x).dot(n));
            if da >= 0.0 {
                out.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                // The crossing, computed from the end that is above so that
                // it lands on the plane and not below it.
                let t = da / (da - db);
                out.push(a + (b - a) * t.clamp(0.0, 1.0));
            }
        }
        if out.len < 3 {
            out.len = 0;
        }
        out
    }

    fn push(&mut self, p: Vec3) {
        // A triangle clipped by one plane has at most four corners; more can
        // only come from rounding and would be a repeated point.
        if self.len < 4 {
            self.corners[self.len] = p;
            self.len += 1;
        }
    }
}

/// Form factor from a differential area at `x` with unit normal `n` to
/// `poly`, which must lie in the half-space `(p - x) · n >= 0`.
///
/// Edges through `x` itself (a receiver point on the source's boundary)
/// subtend no defined angle and are skipped, so touching geometry gives a
/// finite value.
///
/// The (at most four) edges are evaluated side by side in the lanes of
/// `Vec4`s, with the operations of one edge at a time in the same order:
/// a third of a radiosity solve went to this function one edge at a time.
pub fn point_to_polygon(x: Vec3, n: Vec3, poly: &Polygon) -> f32 {
    let c = poly.corners();
    if c.len() < 3 {
        return 0.0;
    }
    // Edge k runs from a[k] to b[k], relative to x; a missing fourth edge
    // is zero and skipped like a degenerate one.
    let (mut a, mut b) = ([[0.0f32; 4]; 3], [[0.0f32; 4]; 3]);
    for k in 0..c.len() {
        let (p, q) = (c[k] - x, c[(k + 1) % c.len()] - x);
        for (axis, (pa, qa)) in [(p.x, q.x), (p.y, q.y), (p.z, q.z)].into_iter().enumerate() {
            a[axis][k] = pa;
            b[axis][k] = qa;
        }
    }
    let t = edge_terms(a.map(Vec4::from_array), b.map(Vec4::from_array), n);
    form_factor(t.x + t.y + t.z + t.w)
}

/// Per lane, the term of the edge from `a` to `b` (x, y, z components,
/// relative to the point) in the sum of [`point_to_polygon`]; zero for an
/// edge through the point.
fn edge_terms([ax, ay, az]: [Vec4; 3], [bx, by, bz]: [Vec4; 3], n: Vec3) -> Vec4 {
    let (cx, cy, cz) = (ay * bz - by * az, az * bx - bz * ax, ax * by - bx * ay);
    let len = (cx * cx + cy * cy + cz * cz).sqrt();
    let valid = len.cmpgt(Vec4::ZERO) & len.cmplt(Vec4::INFINITY);
    let gamma = angle(len, ax * bx + ay * by + az * bz);
    let w = Vec4::splat(n.x) * cx + Vec4::splat(n.y) * cy + Vec4::splat(n.z) * cz;
    Vec4::select(valid, gamma * w / len, Vec4::ZERO)
}

/// The form factor from a sum of edge terms.
fn form_factor(sum: f32) -> f32 {
    // The sign follows the polygon's winding as seen from the point.
    let f = sum.abs() / (2.0 * PI);
    if f.is_finite() {
        f.min(1.0)
    } else {
        0.0
    }
}

/// `atan2(y, x)` for `y > 0` (or `y = 0` and `x != 0`), lane by lane,
/// within 5e-7 rad (two float steps at π): the library's atan2 took an
/// eighth of a radiosity solve. A degree-7 polynomial in `t²` for `atan t`
/// on [0, 1] (Chebyshev fit), with the octant symmetries.
fn angle(y: Vec4, x: Vec4) -> Vec4 {
    const C: [f32; 8] = [
        0.999_999_9,
        -0.333_319_6,
        0.199_692_41,
        -0.140_166_09,
        0.099_061_47,
        -0.059_367_644,
        0.024_166_475,
        -0.004_668_829,
    ];
    let ax = x.abs();
    let steep = y.cmpgt(ax);
    let t = Vec4::select(steep, ax / y, y / ax);
    let t2 = t * t;
    let a = t * C
        .iter()
        .rev()
        .fold(Vec4::ZERO, |acc, &c| acc * t2 + Vec4::splat(c));
    let a = Vec4::select(steep, Vec4::splat(FRAC_PI_2) - a, a);
    Vec4::select(x.cmplt(Vec4::ZERO), Vec4::splat(PI) - a, a)
}

/// Form factors from `x` (unit normal `n`) to the triangle `src`, for each
/// side of the receiver: `[front (+n), back (-n)]`.
pub fn point_to_triangle_sides(x: Vec3, n: Vec3, src: [Vec3; 3]) -> [f32; 2] {
    let poly = Polygon::triangle(src);
    let d = src.map(|v| (v - x).dot(n));
    // A side whose half-space holds no corner sees nothing, one that holds
    // them all sees the whole triangle: only a source across the plane is
    // clipped.
    let side = |sign: f32| {
        if !d.iter().any(|&di| di * sign > 0.0) {
            0.0
        } else if d.iter().all(|&di| di * sign >= 0.0) {
            point_to_polygon(x, n * sign, &poly)
        } else {
            point_to_polygon(x, n * sign, &poly.clip_above(x, n * sign))
        }
    };
    [side(1.0), side(-1.0)]
}

/// [`point_to_triangle_sides`] for four points `xs` of one receiver, bit
/// for bit, with the points side by side in lanes: a link's transfer
/// averages 4 or 16 of them. A point across whose plane the source lies
/// needs its own clip and is evaluated alone.
pub fn points_to_triangle_sides(xs: [Vec3; 4], n: Vec3, src: [Vec3; 3]) -> [[f32; 2]; 4] {
    let lanes = |axis: usize| Vec4::from_array(xs.map(|x| x[axis]));
    let (px, py, pz) = (lanes(0), lanes(1), lanes(2));
    let corners = src.map(|c| {
        [
            Vec4::splat(c.x) - px,
            Vec4::splat(c.y) - py,
            Vec4::splat(c.z) - pz,
        ]
    });
    // Whether each point has source corners in front of it, and behind.
    let (mut front, mut back) = (BVec4A::FALSE, BVec4A::FALSE);
    for [rx, ry, rz] in corners {
        let d = rx * n.x + ry * n.y + rz * n.z;
        front |= d.cmpgt(Vec4::ZERO);
        back |= d.cmplt(Vec4::ZERO);
    }
    if (front & back).any() {
        return xs.map(|x| point_to_triangle_sides(x, n, src));
    }
    let mut sum = Vec4::ZERO;
    for k in 0..3 {
        sum += edge_terms(corners[k], corners[(k + 1) % 3], n);
    }
    // A point that sees neither side gets zero below whatever its sum; and
    // summed from zero, a lane can differ from one edge at a time only in
    // the sign of a zero, which `form_factor` drops.
    let f = sum.to_array();
    let (front, back) = (front.bitmask(), back.bitmask());
    std::array::from_fn(|i| {
        let f = form_factor(f[i]);
        [front, back].map(|m| if m & (1 << i) != 0 { f } else { 0.0 })
    })
}

/// Interior points of `t` that split it into equal areas: the centroids of
/// its `4^level` midpoint-subdivision triangles.
pub fn receiver_points(t: [Vec3; 3], level: u32, out: &mut Vec<Vec3>) {
    if level == 0 {
        out.push((t[0] + t[1] + t[2]) / 3.0);
        return;
    }
    for c in subdivide(t) {
        receiver_points(c, level - 1, out);
    }
}

/// The 4-way midpoint subdivision of a triangle: the three corner triangles
/// (child `k` keeps corner `k`) and the middle one.
pub fn subdivide([a, b, c]: [Vec3; 3]) -> [[Vec3; 3]; 4] {
    let (ab, bc, ca) = ((a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5);
    [[a, ab, ca], [ab, b, bc], [ca, bc, c], [bc, ca, ab]]
}

/// Area-averaged form factor from triangle `recv` to triangle `src`
/// (both sides of the receiver together, no occlusion), from `4^level`
/// receiver points.
pub fn triangle_to_triangle(recv: [Vec3; 3], src: [Vec3; 3], level: u32) -> f32 {
    let n = (recv[1] - recv[0])
        .cross(recv[2] - recv[0])
        .normalize_or_zero();
    let mut pts = Vec::new();
    receiver_points(recv, level, &mut pts);
    let sum: f32 = pts
        .iter()
        .map(|&x| point_to_triangle_sides(x, n, src).iter().sum::<f32>())
        .sum();
    sum / pts.len() as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angle_matches_atan2() {
        let mut worst = 0.0f32;
        for i in 0..=2000 {
            for j in 0..=200 {
                let y = i as f32 / 1000.0;
                let x = j as f32 / 50.0 - 2.0;
                if y > 0.0 || x != 0.0 {
                    let got = angle(Vec4::splat(y), Vec4::splat(x));
                    assert!(got.cmpeq(Vec4::splat(got.x)).all());
                    worst = worst.max((got.x - y.atan2(x)).abs());
                }
            }
        }
        assert!(worst < 1e-6, "worst difference {worst}");
        assert_eq!(angle(Vec4::ZERO, Vec4::NEG_ONE), Vec4::splat(PI));
    }

    #[test]
    fn a_hemisphere_of_polygon_gives_one() {
        // A huge square above the point covers almost the whole hemisphere.
        let s = 1e4;
        let quad = [
            Vec3::new(-s, -s, 1.0),
            Vec3::new(s, -s, 1.0),
            Vec3::new(s, s, 1.0),
            Vec3::new(-s, s, 1.0),
        ];
        let f: f32 = [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]]
            .iter()
            .map(|&t| point_to_triangle_sides(Vec3::ZERO, Vec3::Z, t)[0])
            .sum();
        assert!((f - 1.0).abs() < 1e-3, "{f}");
    }

    #[test]
    fn four_points_at_once_equal_one_at_a_time_bit_for_bit() {
        let mut seed = 7u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
        };
        let mut across = 0;
        for i in 0..2000 {
            let n = Vec3::new(next(), next(), next()).normalize_or(Vec3::Z);
            // Lifted off the plane, most but not all of the time wholly.
            let lift = n * (1.2 + next());
            let src = [(); 3].map(|_| Vec3::new(next(), next(), next()) * 0.5 + lift);
            // Points of one plane through the origin, and now and then one on
            // a source edge (the source then lies across its plane).
            let mut xs = [(); 4].map(|_| {
                let p = Vec3::new(next(), next(), next());
                p - n * p.dot(n)
            });
            if i % 4 == 0 {
                xs[3] = (src[0] + src[1]) * 0.5;
            }
            let got = points_to_triangle_sides(xs, n, src);
            for (x, g) in xs.iter().zip(got) {
                let want = point_to_triangle_sides(*x, n, src);
                assert_eq!(
                    g.map(f32::to_bits),
                    want.map(f32::to_bits),
                    "{x} {n} {src:?}"
                );
            }
            across += usize::from(got.iter().any(|f| f[0] > 0.0 && f[1] > 0.0));
        }
        // Both ways are taken: one point at a time, and all four in lanes.
        assert!(
            (100..1900).contains(&across),
            "{across} of 2000 sets had a source across a point's plane"
        );
    }

    #[test]
    fn a_point_on_the_source_edge_stays_finite() {
        let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let f = point_to_triangle_sides(Vec3::new(0.5, 0.0, 0.0), Vec3::Y, t);
        assert!(f.iter().all(|v| v.is_finite() && *v >= 0.0), "{f:?}");
    }
}
