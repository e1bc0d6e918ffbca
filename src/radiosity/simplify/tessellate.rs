//! Longest-edge bisection down to a maximum edge length and a minimum area.
//!
//! An edge is split, at its midpoint, exactly when it is longer than the
//! limit, whichever of its two triangles splits it: so two triangles that
//! share an edge cut it at the same points, and the patches on both sides
//! share their corners (hence their records). Only the minimum area (which
//! stops slivers, a window bar or a shelf's edge, from turning into hundreds
//! of patches) and the depth guard can leave an edge unsplit on one side.

use glam::Vec3;

/// Splits `tri` until no edge exceeds `max_edge`, a piece's area is at most
/// `min_area`, or `max_depth` levels are used, appending the pieces to
/// `out`. Returns whether the depth guard stopped a piece that was still too
/// long.
pub fn bisect(
    tri: [Vec3; 3],
    max_edge: f32,
    min_area: f32,
    max_depth: u32,
    out: &mut Vec<[Vec3; 3]>,
) -> bool {
    let limit = max_edge * max_edge;
    let mut stack = vec![(tri, 0u32)];
    let mut limited = false;
    while let Some((t, depth)) = stack.pop() {
        // Edge k runs from corner k to corner k + 1.
        let len = |k: usize| t[k].distance_squared(t[(k + 1) % 3]);
        let k = (0..3)
            .max_by(|&a, &b| len(a).total_cmp(&len(b)).then(b.cmp(&a)))
            .unwrap_or(0);
        let area = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length();
        if len(k) <= limit || area <= min_area {
            out.push(t);
            continue;
        }
        if depth >= max_depth {
            limited = true;
            out.push(t);
            continue;
        }
        let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
        let m = (a + b) * 0.5;
        // Same winding as the parent.
        stack.push(([m, b, c], depth + 1));
        stack.push(([a, m, c], depth + 1));
    }
    limited
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(t: &[Vec3; 3]) -> Vec3 {
        0.5 * (t[1] - t[0]).cross(t[2] - t[0])
    }

    #[test]
    fn pieces_are_short_and_cover_the_triangle_with_its_winding() {
        let tri = [
            Vec3::ZERO,
            Vec3::new(3.0, 0.1, 0.0),
            Vec3::new(0.4, 2.0, 0.5),
        ];
        let mut out = Vec::new();
        assert!(!bisect(tri, 0.3, 0.0, 40, &mut out));
        let total: Vec3 = out.iter().map(area).sum();
        assert!((total - area(&tri)).length() < 1e-5 * area(&tri).length());
        for t in &out {
            for k in 0..3 {
                assert!(t[k].distance(t[(k + 1) % 3]) <= 0.3);
            }
            assert!(area(t).dot(area(&tri)) > 0.0);
        }
    }

    #[test]
    fn slivers_stop_at_the_minimum_area() {
        let tri = [Vec3::ZERO, Vec3::X * 10.0, Vec3::new(5.0, 0.01, 0.0)];
        let mut out = Vec::new();
        assert!(!bisect(tri, 0.5, 0.01, 40, &mut out));
        // Area 0.05: halved at most three times before reaching 0.01.
        assert!(out.len() <= 8, "{}", out.len());
        assert!(out.iter().all(|t| area(t).length() > 0.005));
    }

    #[test]
    fn the_depth_guard_stops_and_says_so() {
        let tri = [Vec3::ZERO, Vec3::X * 100.0, Vec3::Y * 100.0];
        let mut out = Vec::new();
        assert!(bisect(tri, 0.01, 0.0, 3, &mut out));
        assert_eq!(out.len(), 8);
    }
}
