//! The hierarchical transport operator (pull, gather over links, push) and
//! the Krylov solver for the reflected radiosity.
//!
//! Unknowns are the reflected radiosities of the leaf elements, one RGB
//! value per side. Channels never mix, so BiCGSTAB runs the three channels
//! in lockstep with per-channel scalars: three independent solves that
//! share each application of the operator.

use std::f32::consts::PI;

use anyhow::{bail, Result};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::hierarchy::{Hierarchy, NONE};
use super::links::{Link, Transfer};
use crate::radiosity::formfactor::point_to_triangle_sides;

/// Per-leaf, per-side RGB values: radiosity or irradiance.
pub type Field = Vec<[Vec3; 2]>;

/// Radiosity of every node after a pull: surface elements hold their
/// area-averaged radiosity per side; every node holds `p = Σ A (B_f + B_b)`
/// and the dipole `dv[axis] = Σ A (B_f − B_b) n[axis]`, from which a
/// cluster's radiant intensity is approximated.
#[derive(Clone, Debug, Default)]
pub struct NodeRadiosity {
    pub b: Vec<[Vec3; 2]>,
    pub p: Vec<Vec3>,
    pub dv: Vec<[Vec3; 3]>,
}

impl NodeRadiosity {
    /// Radiant intensity of node `i` towards unit direction `w`, divided by
    /// nothing: W/sr per unit radiosity scale.
    fn intensity(&self, h: &Hierarchy, i: u32, w: Vec3) -> Vec3 {
        let n = h.node(i);
        let k = i as usize;
        if !n.flat {
            let d = self.dv[k];
            ((self.p[k] * 0.25 + (d[0] * w.x + d[1] * w.y + d[2] * w.z) * 0.5) / PI).max(Vec3::ZERO)
        } else {
            let c = n.normal.dot(w);
            let b = self.b[k];
            (b[0] * c.max(0.0) + b[1] * (-c).max(0.0)) * (n.area / PI)
        }
    }
}

/// The operator `K`: radiosity on leaves to irradiance on leaves.
pub struct Operator<'a> {
    h: &'a Hierarchy,
    /// Links sorted by receiver, and each receiver's range of them.
    links: Vec<Link>,
    groups: Vec<(u32, usize, usize)>,
    order: Vec<u32>,
    pub leaves: Vec<u32>,
    /// Leaf number of each node, `NONE` for inner nodes.
    leaf_of: Vec<u32>,
    /// Leaf areas (the inner-product weights).
    pub area: Vec<f64>,
    /// Per leaf and side, how much more (or less) of the surface links'
    /// kernel the leaf itself sees than the ancestors' averages that reach
    /// it by the push (see [`coverage`]).
    coverage: Vec<[f32; 2]>,
}

impl<'a> Operator<'a> {
    /// The operator of `parts`' links (any order).
    pub fn new(h: &'a Hierarchy, parts: Vec<Vec<Link>>) -> Self {
        let (links, groups) = grouped(parts, h.nodes.len());
        let leaves = h.leaves();
        let mut leaf_of = vec![NONE; h.nodes.len()];
        for (k, &l) in leaves.iter().enumerate() {
            leaf_of[l as usize] = k as u32;
        }
        let area = leaves.iter().map(|&l| h.node(l).area as f64).collect();
        let mut range = vec![(0, 0); h.nodes.len()];
        for &(r, a, b) in &groups {
            range[r as usize] = (a, b);
        }
        // Without the factors a closed room's corner leaves gather more than
        // their whole hemisphere, and with reflectance near one the system
        // stops being solvable.
        let coverage = leaves
            .par_iter()
            .map(|&l| coverage(h, &links, &range, l))
            .collect();
        Self {
            h,
            links,
            groups,
            order: h.top_down(),
            leaves,
            leaf_of,
            area,
            coverage,
        }
    }

    pub fn links(&self) -> &[Link] {
        &self.links
    }

    pub fn into_links(self) -> Vec<Link> {
        self.links
    }

    /// Node radiosities from leaf radiosities.
    pub fn pull(&self, x: &Field) -> NodeRadiosity {
        let n = self.h.nodes.len();
        let mut r = NodeRadiosity {
            b: vec![[Vec3::ZERO; 2]; n],
            p: vec![Vec3::ZERO; n],
            dv: vec![[Vec3::ZERO; 3]; n],
        };
        for &i in self.order.iter().rev() {
            let node = self.h.node(i);
            let k = i as usize;
            if !node.flat {
                for &c in &node.children {
                    let c = c as usize;
                    let (pc, dc) = (r.p[c], r.dv[c]);
                    r.p[k] += pc;
                    for (d, c) in r.dv[k].iter_mut().zip(dc) {
                        *d += c;
                    }
                }
                continue;
            }
            if node.children.is_empty() {
                r.b[k] = x[self.leaf_of[k] as usize];
            } else {
                let mut b = [Vec3::ZERO; 2];
                for &c in &node.children {
                    let w = self.h.node(c).area / node.area;
                    b[0] += r.b[c as usize][0] * w;
                    b[1] += r.b[c as usize][1] * w;
                }
                r.b[k] = b;
            }
            let [f, bk] = r.b[k];
            r.p[k] = (f + bk) * node.area;
            let d = (f - bk) * node.area;
            r.dv[k] = [d * node.normal.x, d * node.normal.y, d * node.normal.z];
        }
        r
    }

    /// Irradiance on the leaves from leaf radiosities `x`.
    pub fn apply(&self, x: &Field) -> Field {
        let rad = self.pull(x);
        let h = self.h;
        let gathered: Vec<([Vec3; 2], [Vec3; 2], [Vec3; 4])> = self
            .groups
            .par_iter()
            .map(|&(r, a, b)| {
                let nr = h.node(r);
                let mut gs = [Vec3::ZERO; 2];
                let mut gp = [Vec3::ZERO; 2];
                let mut gv = [Vec3::ZERO; 4];
                for l in &self.links[a..b] {
                    match l.t {
                        Transfer::Surfaces { f, vis, .. } => {
                            let bs = rad.b[l.s as usize];
                            for side in 0..2 {
                                let (f, v) = (f[side], vis[side]);
                                gs[side] += bs[0] * (f[0] * v[0]) + bs[1] * (f[1] * v[1]);
                            }
                        }
                        Transfer::Point { dir, g, vis } => {
                            let e = rad.intensity(h, l.s, -dir) * (g * vis);
                            if !nr.flat {
                                gv[0] += e * dir.x;
                                gv[1] += e * dir.y;
                                gv[2] += e * dir.z;
                                gv[3] += e;
                            } else {
                                let c = nr.normal.dot(dir);
                                gp[0] += e * c.max(0.0);
                                gp[1] += e * (-c).max(0.0);
                            }
                        }
                    }
                }
                (gs, gp, gv)
            })
            .collect();
        // Irradiance through surface links (`gs`), through cluster links
        // (`gp`), and a cluster's incident light to first order (`gv`: the
        // vector irradiance, then the sum of the links' irradiances).
        let n = h.nodes.len();
        let mut gs = vec![[Vec3::ZERO; 2]; n];
        let mut gp = vec![[Vec3::ZERO; 2]; n];
        let mut gv = vec![[Vec3::ZERO; 4]; n];
        for (&(r, _, _), (s, p, v)) in self.groups.iter().zip(gathered) {
            gs[r as usize] = s;
            gp[r as usize] = p;
            gv[r as usize] = v;
        }
        // Push: irradiance is per unit area, so children inherit it as is.
        // A cluster's incident light reaches each surface of orientation `m`
        // as `E(m) = Σe/4 + (Σe ω)·m/2`, the irradiance of the light's
        // first-order (constant plus linear) expansion: exact for light from
        // all around, and right on average over orientations for any light.
        // The vector alone (`max(0, (Σe ω)·m)`) cancels where light comes
        // from several sides: a ball in a room received a third too little.
        for &i in &self.order {
            let node = h.node(i);
            let k = i as usize;
            let (pgs, pgp, pgv) = (gs[k], gp[k], gv[k]);
            for &c in &node.children {
                let c = c as usize;
                if !node.flat {
                    let child = &h.nodes[c];
                    if !child.flat {
                        for a in 0..4 {
                            gv[c][a] += pgv[a];
                        }
                    } else {
                        let m = child.normal;
                        let e = (pgv[0] * m.x + pgv[1] * m.y + pgv[2] * m.z) * 0.5;
                        let iso = pgv[3] * 0.25;
                        gp[c][0] += (iso + e).max(Vec3::ZERO);
                        gp[c][1] += (iso - e).max(Vec3::ZERO);
                    }
                } else {
                    for side in 0..2 {
                        gs[c][side] += pgs[side];
                        gp[c][side] += pgp[side];
                    }
                }
            }
        }
        self.leaves
            .iter()
            .zip(&self.coverage)
            .map(|(&l, c)| {
                let l = l as usize;
                [gs[l][0] * c[0] + gp[l][0], gs[l][1] * c[1] + gp[l][1]]
            })
            .collect()
    }

    /// Area-weighted per-channel inner product.
    fn dot(&self, u: &Field, v: &Field) -> DVec3 {
        u.iter()
            .zip(v)
            .zip(&self.area)
            .map(|((a, b), &w)| (a[0] * b[0] + a[1] * b[1]).as_dvec3() * w)
            .sum()
    }
}

/// `links` grouped by receiver, and each receiver's range of them. A
/// counting sort over the `nodes` receivers: in one pass, where sorting by
/// receiver and source took a tenth of a solve, and stable, so that each
/// receiver's links keep the order they came in (a round's links behind the
/// ones it kept from the last).
fn grouped(parts: Vec<Vec<Link>>, nodes: usize) -> (Vec<Link>, Vec<(u32, usize, usize)>) {
    let mut start = vec![0usize; nodes + 1];
    for l in parts.iter().flatten() {
        start[l.r as usize + 1] += 1;
    }
    for i in 0..nodes {
        start[i + 1] += start[i];
    }
    let groups = (0..nodes)
        .filter(|&r| start[r + 1] > start[r])
        .map(|r| (r as u32, start[r], start[r + 1]))
        .collect();
    // Where each place's link comes from: (part, index in the part).
    let mut from = vec![(0u32, 0u32); start[nodes]];
    for (p, part) in parts.iter().enumerate() {
        for (i, l) in part.iter().enumerate() {
            let at = &mut start[l.r as usize];
            from[*at] = (p as u32, i as u32);
            *at += 1;
        }
    }
    let links = from
        .par_iter()
        .map(|&(p, i)| parts[p as usize][i as usize])
        .collect();
    (links, groups)
}

/// The push hands a leaf its ancestors' area-averaged form factors, which
/// misjudge what a leaf in a corner sees: summed over many links the error
/// no single link's oracle notices adds up (a furnace's corner leaves gather
/// 30% too much). The leaf's own point form factors at its centroid, with
/// each link's visibility, over what the links deliver give a per-side
/// factor that restores it; in a closed room both sums are exactly one at
/// every point, so energy is conserved leaf by leaf.
fn coverage(h: &Hierarchy, links: &[Link], range: &[(usize, usize)], leaf: u32) -> [f32; 2] {
    let node = h.node(leaf);
    let (x, n) = (node.center, node.normal);
    let mut seen = [0.0f32; 2];
    let mut given = [0.0f32; 2];
    let mut a = leaf;
    while a != NONE && !h.node(a).cluster {
        let (lo, hi) = range[a as usize];
        for l in &links[lo..hi] {
            if let Transfer::Surfaces { f, vis, .. } = l.t {
                let p = point_to_triangle_sides(x, n, h.node(l.s).tri);
                for side in 0..2 {
                    let (f, v) = (f[side], vis[side]);
                    let visible = f[0] * v[0] + f[1] * v[1];
                    let total = f[0] + f[1];
                    if total > 0.0 {
                        seen[side] += visible / total * p[side];
                    }
                    given[side] += visible;
                }
            }
        }
        a = h.node(a).parent;
    }
    [0, 1].map(|side| {
        let c = seen[side] / given[side];
        // A guard against leaves whose links deliver next to nothing.
        if c.is_finite() && given[side] > 1e-6 {
            c.clamp(0.1, 10.0)
        } else {
            1.0
        }
    })
}

/// Outcome of [`solve`].
pub struct Solved {
    pub x: Field,
    pub iterations: usize,
    /// Largest per-channel relative residual ‖b − A x‖ / ‖b‖.
    pub residual: f64,
}

impl Solved {
    /// An error unless the residual is at most `bound`: [`solve`] stops on
    /// breakdown or stagnation as well as on convergence, and a stalled
    /// iterate (at worst the zero guess, residual 1) must not pass for a
    /// solution.
    pub fn check(&self, bound: f64) -> Result<()> {
        if self.residual <= bound {
            return Ok(());
        }
        bail!(
            "the radiosity solve did not converge: relative residual {:.3e} after {} \
             iterations (BiCGSTAB, then fixed point), above the {bound:.0e} a solution must reach",
            self.residual,
            self.iterations
        )
    }
}

/// Solves `x − ρ ⊙ K x = b` by BiCGSTAB from the guess `x`, to relative
/// residual `tol` per channel or `max_iter` iterations in all.
///
/// BiCGSTAB can stall when one channel's recurrence breaks down (its shadow
/// residual turns orthogonal) while the others go on, and its updated
/// residual drifts from the true one in single precision. So it runs in
/// cycles: each ends on convergence, breakdown, divergence or stagnation,
/// and the next restarts from the true residual of the best iterate, as
/// long as the true residual keeps falling. What the cycles leave, the
/// fixed-point iteration finishes.
pub fn solve(
    op: &Operator,
    rho: &[Vec3],
    b: &Field,
    x: Field,
    tol: f64,
    max_iter: usize,
) -> Solved {
    let apply = |v: &Field| -> Field {
        let k = op.apply(v);
        v.iter()
            .zip(&k)
            .zip(rho)
            .map(|((v, k), &r)| [v[0] - r * k[0], v[1] - r * k[1]])
            .collect()
    };
    iterate(&apply, &|u, v| op.dot(u, v), b, x, tol, max_iter)
}

/// [`solve`] for any operator `apply` and inner product `dot`.
fn iterate(
    apply: &dyn Fn(&Field) -> Field,
    dot: &dyn Fn(&Field, &Field) -> DVec3,
    b: &Field,
    mut x: Field,
    tol: f64,
    max_iter: usize,
) -> Solved {
    let bnorm = dot(b, b).map(f64::sqrt);
    let rel = |r: &Field| -> f64 {
        let n = dot(r, r).map(f64::sqrt);
        let mut worst = 0.0f64;
        for c in 0..3 {
            if bnorm[c] > 0.0 {
                worst = worst.max(n[c] / bnorm[c]);
            }
        }
        worst
    };
    let true_residual = |x: &Field| combine(b, &apply(x), DVec3::NEG_ONE);
    let mut iterations = 0;
    let mut r = true_residual(&x);
    let mut res = rel(&r);
    while res > tol && iterations < max_iter {
        let before = res;
        let (next, used) = cycle(apply, dot, &rel, &r, x.clone(), tol, max_iter - iterations);
        iterations += used;
        let r_next = true_residual(&next);
        let res_next = rel(&r_next);
        if res_next >= before || res_next.is_nan() {
            break;
        }
        (x, r, res) = (next, r_next, res_next);
        if used == 0 || res_next > 0.5 * before && res_next <= 10.0 * tol {
            break;
        }
    }
    // Where BiCGSTAB gains nothing (the unsimplified studio at q = 0.6: a
    // cycle that diverged, then restarts that gain a few percent each), the
    // plain fixed-point iteration `x ← b + ρ K x` still converges, at the
    // rate of ρK's largest eigenvalue, as long as ρK is a contraction: every
    // leaf gathers at most about its hemisphere and reflects less than it
    // gathers. It runs for as long as the true residual keeps falling.
    while res > tol && iterations < max_iter {
        let next = combine(&x, &r, DVec3::ONE);
        let r_next = true_residual(&next);
        let res_next = rel(&r_next);
        iterations += 1;
        if res_next >= res || res_next.is_nan() {
            break;
        }
        (x, r, res) = (next, r_next, res_next);
    }
    Solved {
        residual: res,
        x,
        iterations,
    }
}

/// A cycle whose residual grows this far past its best has diverged (the
/// unsimplified studio's went from 1e-3 to 2e11 over 500 iterations): it
/// stops and hands back its best iterate.
const DIVERGED: f64 = 100.0;

/// One BiCGSTAB cycle from `x` with true residual `r`; returns the new
/// iterate and the iterations it took.
fn cycle(
    apply: &dyn Fn(&Field) -> Field,
    dot: &dyn Fn(&Field, &Field) -> DVec3,
    rel: &dyn Fn(&Field) -> f64,
    r: &Field,
    mut x: Field,
    tol: f64,
    max_iter: usize,
) -> (Field, usize) {
    let mut r = r.clone();
    let r0 = r.clone();
    let mut res = rel(&r);
    let mut best = (res, x.clone());
    let mut iterations = 0;
    let (mut rho_old, mut alpha, mut omega) = (DVec3::ONE, DVec3::ONE, DVec3::ONE);
    let mut v = zero(r.len());
    let mut p = zero(r.len());
    while res > tol && iterations < max_iter {
        iterations += 1;
        let rho_new = dot(&r0, &r);
        let beta = div(rho_new, rho_old) * div(alpha, omega);
        // p = r + beta (p - omega v)
        let pv = combine(&p, &v, -omega);
        p = combine(&r, &pv, beta);
        v = apply(&p);
        alpha = div(rho_new, dot(&r0, &v));
        let s = combine(&r, &v, -alpha);
        if rel(&s) <= tol {
            x = combine(&x, &p, alpha);
            return (x, iterations);
        }
        let t = apply(&s);
        omega = div(dot(&t, &s), dot(&t, &t));
        x = combine(&x, &p, alpha);
        x = combine(&x, &s, omega);
        r = combine(&s, &t, -omega);
        res = rel(&r);
        rho_old = rho_new;
        if res < best.0 {
            // Into the buffer already held: no allocation per iteration.
            best.0 = res;
            best.1.clone_from(&x);
        } else if res > DIVERGED * best.0 {
            break;
        }
        // A channel whose recurrence broke down stalls the cycle: restart.
        let left = dot(&r, &r);
        if (0..3).any(|c| (omega[c] == 0.0 || rho_new[c] == 0.0) && left[c] > 0.0)
            || !res.is_finite()
        {
            break;
        }
    }
    (best.1, iterations)
}

fn zero(n: usize) -> Field {
    vec![[Vec3::ZERO; 2]; n]
}

/// `u + c ⊙ v`, per channel.
fn combine(u: &Field, v: &Field, c: DVec3) -> Field {
    let c = c.as_vec3();
    u.iter()
        .zip(v)
        .map(|(a, b)| [a[0] + b[0] * c, a[1] + b[1] * c])
        .collect()
}

/// Per-channel quotient, zero where the denominator vanishes (a channel
/// that has converged or carries no light).
fn div(a: DVec3, b: DVec3) -> DVec3 {
    let f = |a: f64, b: f64| {
        if b != 0.0 && (a / b).is_finite() {
            a / b
        } else {
            0.0
        }
    };
    DVec3::new(f(a.x, b.x), f(a.y, b.y), f(a.z, b.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn solved(residual: f64) -> Solved {
        Solved {
            x: Vec::new(),
            iterations: 7,
            residual,
        }
    }

    /// Per-channel sum of products, both sides.
    fn plain_dot(u: &Field, v: &Field) -> DVec3 {
        u.iter().zip(v).fold(DVec3::ZERO, |acc, (a, b)| {
            acc + (a[0] * b[0] + a[1] * b[1]).as_dvec3()
        })
    }

    /// `x − ρ P x` for the cyclic shift `P` (each element gathers all its
    /// light from the next, both sides): its eigenvalues `1 − ρ e^{iθ}`
    /// ring the origin at `1 − ρ`.
    fn shift(x: &Field, rho: Vec3) -> Field {
        let n = x.len();
        (0..n)
            .map(|i| {
                let next = x[(i + 1) % n];
                [x[i][0] - rho * next[0], x[i][1] - rho * next[1]]
            })
            .collect()
    }

    #[test]
    fn solves_a_system_bicgstab_alone_cannot() {
        let rho = Vec3::new(0.97, 0.9, 0.6);
        let n = 97;
        let b: Field = (0..n)
            .map(|i| {
                let v = Vec3::new(1.0 + (i % 7) as f32, 2.0 + (i % 3) as f32, 0.5);
                [v, v * 0.5]
            })
            .collect();
        let apply = |x: &Field| shift(x, rho);
        let solved = iterate(&apply, &plain_dot, &b, zero(n), 1e-5, 500);
        // Checked against the residual recomputed here.
        let r = combine(&b, &apply(&solved.x), DVec3::NEG_ONE);
        let (rr, bb) = (plain_dot(&r, &r), plain_dot(&b, &b));
        for c in 0..3 {
            let rel = (rr[c] / bb[c]).sqrt();
            assert!(
                rel <= 1e-5,
                "channel {c}: relative residual {rel:.3e}, {} iterations",
                solved.iterations
            );
        }
        solved.check(1e-5).unwrap();
    }

    #[test]
    fn a_stalled_solve_is_an_error() {
        let err = solved(1.0).check(1e-3).unwrap_err().to_string();
        assert!(err.contains("did not converge"), "{err}");
        assert!(
            err.contains("1.000e0") && err.contains("7 iterations"),
            "{err}"
        );
        assert!(solved(f64::NAN).check(1e-3).is_err());
        assert!(solved(2e-3).check(1e-3).is_err());
        solved(1e-3).check(1e-3).unwrap();
        solved(0.0).check(1e-3).unwrap();
    }
}
