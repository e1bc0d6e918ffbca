//! Links between nodes: refinement by the transported-power oracle, then
//! form factors and visibility for the accepted ones.

use glam::Vec3;
use rayon::prelude::*;

use super::extent::{kernel, End};
use super::hierarchy::{Hierarchy, Node, FLAT_COS, NONE};
use super::linear::NodeRadiosity;
use super::pruned::Pruned;
use crate::accel::{Hit, RayEngine};
use crate::radiosity::formfactor::{
    point_to_triangle_sides, points_to_triangle_sides, receiver_points,
};
use crate::ray::{offset_origin, Ray};

/// How light gets from a link's source to its receiver.
#[derive(Clone, Copy, Debug)]
pub enum Transfer {
    /// Between two surface elements: `f[a][b]` is the unoccluded
    /// area-averaged form factor from receiver side `a` to source side `b`
    /// (0 = front), `vis[a][b]` its visible fraction.
    Surfaces {
        f: [[f32; 2]; 2],
        vis: [[f32; 2]; 2],
        /// The oracle's smallest and largest point form factor over the
        /// receiver, kept so that later rounds judge the link without
        /// evaluating them again.
        spread: Spread,
    },
    /// From or to a cluster, treated as a point at its centre: `dir` is the
    /// unit direction from receiver to source, `g` the inverse squared
    /// distance, `vis` the visible fraction.
    Point { dir: Vec3, g: f32, vis: f32 },
}

/// Smallest and largest point form factor over a receiver (see
/// [`ff_range`]); zero for pairs with a cluster.
pub type Spread = [f32; 2];

#[derive(Clone, Copy, Debug)]
pub struct Link {
    pub r: u32,
    pub s: u32,
    pub t: Transfer,
    /// First of the link's shadow-ray outcomes in the solve's sample list,
    /// [`ALL_OPEN`] for a link none of whose rays was blocked.
    pub samples: u32,
}

/// The `samples` of a link whose rays all passed: its visible fractions
/// are one whatever the sources' radiosities, so there is nothing to
/// re-weigh and its outcomes are not kept (seven links in ten on the
/// Cornell box).
const ALL_OPEN: u32 = u32::MAX;

impl Link {
    /// The link with its outcomes `offset` further on in the sample list.
    fn shifted(self, offset: u32) -> Self {
        let samples = match self.samples {
            ALL_OPEN => ALL_OPEN,
            first => first + offset,
        };
        Self { samples, ..self }
    }
}

/// One shadow ray's outcome, kept so that visibility can be re-weighed
/// when the source's radiosity changes without tracing again.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    /// The source leaf the ray ended on (at the time it was traced).
    pub leaf: u32,
    /// Receiver side and source side (0 = front).
    pub sides: (u8, u8),
    /// The share of the ray's light that gets through, in 255ths: 0 when
    /// blocked, 255 when open, between when only left-out geometry stands
    /// in the way (see [`Pruned`]).
    pub pass: u8,
    /// Whether the ray's source point lies in a contact shadow too small
    /// for its element (see [`buried_probe`]).
    pub buried: bool,
}

impl Sample {
    fn open(&self) -> bool {
        self.pass == u8::MAX
    }

    fn share(&self) -> f32 {
        f32::from(self.pass) * (1.0 / 255.0)
    }
}

impl Transfer {
    /// Whether the rays found the link partly hidden.
    pub fn partial(&self) -> bool {
        let part = |v: f32| v > 0.0 && v < 1.0;
        match self {
            Transfer::Surfaces { vis, .. } => vis.iter().flatten().any(|&v| part(v)),
            Transfer::Point { vis, .. } => part(*vis),
        }
    }
}

/// The part of a link's form factor counted as error on top of the
/// kernel's spread, for partial visibility within the elements.
const VISIBILITY_SHARE: f32 = 0.25;

/// The same for a link whose rays found it partly hidden (see
/// `Refiner::verdict`).
const PARTIAL_SHARE: f32 = 1.0;

/// A blocker closer to a source point than this share of its leaf's
/// radius casts a shadow there that the leaf cannot resolve (the wall
/// behind a chair rail that touches it, or a centimetre off): the leaf's
/// average radiosity already counts that part dark, since the rays it
/// gathered with from there were blocked too. A shadow ray blocked there
/// would count it dark a second time, so it is left out of the visible
/// fraction (see [`Visibility`]). In the soda shop's room with white chair
/// rails this second count alone took about half the rails' excess loss.
const CONTACT: f32 = 0.5;

/// What the oracle makes of a pair of nodes.
enum Verdict {
    /// Nothing can pass (coplanar surfaces, back to back).
    Drop,
    Accept,
    /// Too much power for one link, or a cluster too close for its
    /// point approximation.
    Split,
}

pub struct Refiner<'a> {
    /// Source radiosity the oracle weighs links with; nodes created after
    /// it was computed take their nearest ancestor's.
    pub radiosity: &'a NodeRadiosity,
    /// A link's error estimate may reach this much power (W).
    pub max_error: f32,
    /// Pairs to compute form factors for, with their spread.
    pub pending: Vec<(u32, u32, Spread)>,
}

impl Refiner<'_> {
    /// Links for each of `pairs` (`r` gathering from `s`, or for `r == s`
    /// everything within `r`), down to where the oracle is satisfied.
    ///
    /// A level of pairs at a time: the verdicts, which evaluate form
    /// factors, are judged in parallel on the hierarchy as it stands, and
    /// only the splits, which add nodes to it, are made in order.
    pub fn refine(&mut self, h: &mut Hierarchy, mut pairs: Vec<(u32, u32)>) {
        while !pairs.is_empty() {
            let verdicts: Vec<Option<(Verdict, Spread)>> = pairs
                .par_iter()
                .map(|&(r, s)| (r != s).then(|| self.verdict(h, r, s, false, None)))
                .collect();
            let mut next = Vec::new();
            for (&(r, s), verdict) in pairs.iter().zip(verdicts) {
                let Some((verdict, spread)) = verdict else {
                    if h.node(r).cluster {
                        let kids = h.split(r);
                        next.extend(kids.iter().flat_map(|&a| kids.iter().map(move |&b| (a, b))));
                    }
                    continue;
                };
                match verdict {
                    Verdict::Drop => {}
                    Verdict::Accept => self.pending.push((r, s, spread)),
                    Verdict::Split => match self.which(h, r, s) {
                        Some(true) => next.extend(h.split(r).into_iter().map(|c| (c, s))),
                        Some(false) => next.extend(h.split(s).into_iter().map(|c| (r, c))),
                        None => self.pending.push((r, s, spread)),
                    },
                }
            }
            pairs = next;
        }
    }

    /// Which of `links` the oracle would split under the current
    /// radiosities; judged in parallel, since most stay.
    pub fn to_split(&self, h: &Hierarchy, links: &[Link]) -> Vec<bool> {
        links
            .par_iter()
            .map(|l| {
                let spread = match l.t {
                    Transfer::Surfaces { spread, .. } => Some(spread),
                    Transfer::Point { .. } => None,
                };
                matches!(
                    self.verdict(h, l.r, l.s, l.t.partial(), spread).0,
                    Verdict::Split
                ) && self.which(h, l.r, l.s).is_some()
            })
            .collect()
    }

    /// The pairs that replace an existing link, for [`Self::refine`].
    pub fn split_link(&self, h: &mut Hierarchy, r: u32, s: u32) -> Vec<(u32, u32)> {
        match self.which(h, r, s) {
            Some(true) => h.split(r).into_iter().map(|c| (c, s)).collect(),
            _ => h.split(s).into_iter().map(|c| (r, c)).collect(),
        }
    }

    /// Which end to split: `Some(true)` the receiver, `Some(false)` the
    /// source, `None` neither can be.
    fn which(&self, h: &Hierarchy, r: u32, s: u32) -> Option<bool> {
        let (nr, ns) = (h.node(r), h.node(s));
        if spans_planes(nr) {
            return Some(true);
        }
        // A cluster close to the other end must open up, whatever its size.
        let overlap = nr.center.distance(ns.center) <= nr.radius + ns.radius;
        if overlap && (nr.cluster || ns.cluster) {
            return Some(if nr.cluster && ns.cluster {
                nr.radius >= ns.radius
            } else {
                nr.cluster
            });
        }
        match (h.splittable(r), h.splittable(s)) {
            (true, true) => Some(nr.radius >= ns.radius),
            (true, false) => Some(true),
            (false, true) => Some(false),
            (false, false) => None,
        }
    }

    /// `partial`: whether the link's rays found it partly hidden. Its two
    /// ends then average lit and shadowed parts, and multiplying their
    /// averages counts the shadow twice (a floor element half under a box
    /// is both half dark and half hidden), so the whole magnitude is error.
    /// `spread`: the pair's form factor spread if known from an earlier
    /// round; the verdict comes with it.
    fn verdict(
        &self,
        h: &Hierarchy,
        r: u32,
        s: u32,
        partial: bool,
        spread: Option<Spread>,
    ) -> (Verdict, Spread) {
        let (nr, ns) = (h.node(r), h.node(s));
        let mut range = [0.0; 2];
        if spans_planes(nr) {
            return (Verdict::Split, range);
        }
        let power = if !nr.cluster && !ns.cluster {
            if spread.is_none() && coplanar(nr, ns) {
                return (Verdict::Drop, range);
            }
            let b = self.surface_b(h, s);
            let bmax = b[0].max(b[1]).max_element();
            // What piecewise-constant irradiance gets wrong over the
            // receiver (the kernel's spread), plus a share of the
            // magnitude for visibility a few rays do not resolve.
            let share = if partial {
                PARTIAL_SHARE
            } else {
                VISIBILITY_SHARE
            };
            range = match spread {
                Some(known) => known,
                None => {
                    // The centroid's form factor alone is a lower bound on
                    // the largest: when its share already exceeds the
                    // bound, the pair is split without the corners (most
                    // pairs the refinement visits are split). A pair
                    // neither of whose ends splits needs its spread.
                    let centre = ff_at(nr, ns, nr.center);
                    let can_split = h.splittable(r) || h.splittable(s);
                    if can_split && share * centre * nr.area * bmax > self.max_error {
                        return (Verdict::Split, range);
                    }
                    ff_range(nr, ns, centre)
                }
            };
            let [lo, hi] = range;
            if hi.is_nan() || hi <= 0.0 {
                return (Verdict::Drop, range);
            }
            ((hi - lo) + share * hi) * nr.area * bmax
        } else {
            if flat_coplanar(nr, ns) {
                return (Verdict::Drop, range);
            }
            let d = nr.center.distance(ns.center) - nr.radius - ns.radius;
            if d <= 0.0 {
                return (Verdict::Split, range);
            }
            let i = self.max_intensity(h, s);
            i / (d * d) * nr.area
        };
        // Links that carry nothing yet stay, coarse, for later rounds to
        // weigh with the light that reaches their source by then.
        let verdict = if power > self.max_error {
            Verdict::Split
        } else {
            Verdict::Accept
        };
        (verdict, range)
    }

    fn known(&self, h: &Hierarchy, mut i: u32) -> u32 {
        while i as usize >= self.radiosity.b.len() {
            i = h.node(i).parent;
        }
        i
    }

    /// The weight a ray ending on `leaf`'s `side` gets in visible fractions.
    pub fn weight(&self, h: &Hierarchy, leaf: u32, side: usize) -> f32 {
        self.surface_b(h, leaf)[side].max_element()
    }

    fn surface_b(&self, h: &Hierarchy, s: u32) -> [Vec3; 2] {
        self.radiosity.b[self.known(h, s) as usize]
    }

    fn max_intensity(&self, h: &Hierarchy, s: u32) -> f32 {
        let n = h.node(s);
        if !n.flat {
            let k = s as usize;
            let p = self.radiosity.p[k];
            let d = self.radiosity.dv[k];
            let dl = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).powf(0.5);
            ((p * 0.25 + dl * 0.5) / std::f32::consts::PI).max_element()
        } else {
            let b = self.surface_b(h, s);
            n.area * b[0].max(b[1]).max_element() / std::f32::consts::PI
        }
    }
}

/// Whether `n` is a flat cluster over several parallel planes (a floor and
/// the tops of the boxes on it). As a source it radiates like one surface,
/// but as a receiver it would hand every surface the same irradiance:
/// the floor's, partly hidden by the boxes, on the box tops too, which left
/// them a sixth too dark. Such a receiver is opened up instead.
fn spans_planes(n: &Node) -> bool {
    n.cluster && n.flat && n.plane[1] - n.plane[0] > 1e-4 * n.radius
}

/// Whether the source lies in the receiver's plane (nothing passes).
fn coplanar(r: &Node, s: &Node) -> bool {
    let tol = 1e-5 * (r.radius + s.radius);
    s.tri
        .iter()
        .all(|&p| (p - r.center).dot(r.normal).abs() <= tol)
}

/// Whether two flat nodes lie in one plane, facing either way.
fn flat_coplanar(r: &Node, s: &Node) -> bool {
    if !(r.flat && s.flat) {
        return false;
    }
    let c = r.normal.dot(s.normal);
    let along = if c >= FLAT_COS {
        s.plane
    } else if c <= -FLAT_COS {
        [-s.plane[1], -s.plane[0]]
    } else {
        return false;
    };
    let tol = 1e-5 * (r.radius + s.radius);
    let at = r.plane[0];
    r.plane[1] - at <= tol && (along[0] - at).abs() <= tol && (along[1] - at).abs() <= tol
}

/// The two ends of a link for [`kernel`].
fn ends<'a>(r: &'a Node, s: &'a Node) -> (End<'a>, End<'a>) {
    let end = |n: &'a Node| -> End<'a> { (&n.extent, n.flat.then_some(n.normal)) };
    (end(r), end(s))
}

/// The point form factor from `x` on `r` to `s`, the larger of the two
/// sides.
fn ff_at(r: &Node, s: &Node, x: Vec3) -> f32 {
    let f = point_to_triangle_sides(x, r.normal, s.tri);
    f[0].max(f[1])
}

/// The smallest and largest point form factor (either side) over the
/// receiver: at its centroid (`centre`, already evaluated) and near its
/// corners, where an adjacent source is seen most.
fn ff_range(r: &Node, s: &Node, centre: f32) -> Spread {
    let c = r.center;
    let [a, b, d] = r.tri;
    let near = |p: Vec3| p + (c - p) * 0.05;
    // Three points in four lanes, the last a repeat.
    let xs = [near(a), near(b), near(d), near(a)];
    points_to_triangle_sides(xs, r.normal, s.tri)[..3]
        .iter()
        .map(|f| f[0].max(f[1]))
        .fold(
            [f32::INFINITY.min(centre), 0.0f32.max(centre)],
            |[lo, hi], f| [lo.min(f), hi.max(f)],
        )
}

/// Form factors and visibility of `pairs`, traced in batches. Returns the
/// links, in parts as the batches made them, and the rays traced; the
/// outcomes a link's visibility can be re-weighed from are appended to
/// `samples`, `rays` per link, where its `samples` points.
/// `weight(leaf, side)` is the source radiosity the visible fractions are
/// weighed with (see [`reweigh`]); rays that only left-out geometry blocks
/// pass with its share (see [`Pruned`]).
pub fn compute(
    h: &Hierarchy,
    pairs: &[(u32, u32, Spread)],
    engine: &dyn RayEngine,
    pruned: &Pruned,
    rays: usize,
    weight: &(dyn Fn(u32, usize) -> f32 + Sync),
    samples: &mut Vec<Sample>,
) -> (Vec<Vec<Link>>, u64) {
    let out: Vec<(Vec<Link>, Vec<Sample>, usize)> = pairs
        .par_chunks(128)
        .map(|chunk| {
            let mut batch = Vec::with_capacity(chunk.len() * rays);
            let mut samples = Vec::with_capacity(batch.capacity());
            for &(r, s, _) in chunk {
                let seed = hash3(r, s, 0);
                for j in 0..rays {
                    let (ray, sample) = shadow_ray(h, r, s, seed, j, rays);
                    batch.push(ray);
                    samples.push(sample);
                }
            }
            let mut pass = vec![0; batch.len()];
            pruned.pass_batch(engine, &batch, &mut pass);
            for (s, p) in samples.iter_mut().zip(pass) {
                s.pass = p;
            }
            // Blocked rays whose source end is in a contact shadow.
            let (probes, which): (Vec<Ray>, Vec<usize>) = batch
                .iter()
                .zip(&samples)
                .enumerate()
                .filter(|(_, (_, sample))| sample.pass == 0)
                .filter_map(|(k, (ray, sample))| Some((buried_probe(h, ray, sample.leaf)?, k)))
                .unzip();
            let mut hit = vec![false; probes.len()];
            engine.occluded_batch(&probes, &mut hit);
            for (&k, b) in which.iter().zip(hit) {
                samples[k].buried = b;
            }
            let mut links = Vec::with_capacity(chunk.len());
            let mut points = Vec::with_capacity(16);
            let mut kept = Vec::with_capacity(samples.len());
            for (k, &(r, s, spread)) in chunk.iter().enumerate() {
                let mine = &samples[k * rays..(k + 1) * rays];
                if mine.iter().all(|s| s.pass == 0) {
                    continue;
                }
                let vis = Visibility::weighed(mine, weight);
                let first = if mine.iter().all(Sample::open) {
                    ALL_OPEN
                } else {
                    kept.extend_from_slice(mine);
                    (kept.len() - rays) as u32
                };
                links.push(Link {
                    r,
                    s,
                    t: transfer(h, r, s, &vis, spread, &mut points),
                    samples: first,
                });
            }
            (links, kept, probes.len())
        })
        .collect();
    let mut parts = Vec::with_capacity(out.len());
    let mut traced = (pairs.len() * rays) as u64;
    for (mut links, kept, probes) in out {
        traced += probes as u64;
        let offset = samples.len() as u32;
        for l in &mut links {
            *l = l.shifted(offset);
        }
        samples.extend(kept);
        parts.push(links);
    }
    (parts, traced)
}

/// Visible fractions again, weighed with new source radiosities.
pub fn reweigh(
    links: &mut [Link],
    samples: &[Sample],
    rays: usize,
    weight: &(dyn Fn(u32, usize) -> f32 + Sync),
) {
    links.par_iter_mut().for_each(|l| {
        if l.samples == ALL_OPEN {
            return;
        }
        let first = l.samples as usize;
        let vis = Visibility::weighed(&samples[first..first + rays], weight);
        match &mut l.t {
            Transfer::Surfaces { vis: v, .. } => *v = vis.pair,
            Transfer::Point { vis: v, .. } => *v = vis.overall,
        }
    });
}

/// Visible fractions of a link's rays, per pair of sides they join: a
/// receiver side only sees the part of the source in its half-space, so
/// rays to the other half say nothing about it (a box standing on the
/// floor hides the light from its inner side, not from its outer one).
///
/// Each ray counts with the radiosity of the source leaf it ends on: an
/// element's average radiosity already includes its dark parts (a floor
/// element half under a box), and counting their hidden rays again would
/// darken it twice. For the same reason a ray whose source end lies in a
/// contact shadow (see [`CONTACT`]) does not count at all: the leaf's
/// radiosity there is not its average but next to nothing.
struct Visibility {
    overall: f32,
    /// `[receiver side][source side]`.
    pair: [[f32; 2]; 2],
}

impl Visibility {
    fn weighed(samples: &[Sample], weight: &dyn Fn(u32, usize) -> f32) -> Self {
        // Most links are wholly open, and then every fraction is one
        // whatever the weights: skip weighing them.
        if samples.iter().all(Sample::open) {
            return Self {
                overall: 1.0,
                pair: [[1.0; 2]; 2],
            };
        }
        let by = |w: &dyn Fn(&Sample) -> f32| {
            let mut open = [[0.0f32; 2]; 2];
            let mut all = [[0.0f32; 2]; 2];
            for s in samples {
                if s.buried {
                    continue;
                }
                let (a, b) = (s.sides.0 as usize, s.sides.1 as usize);
                let w = w(s);
                all[a][b] += w;
                open[a][b] += w * s.share();
            }
            (open, all)
        };
        let (mut open, mut all) = by(&|s| weight(s.leaf, s.sides.1 as usize));
        if all.iter().flatten().sum::<f32>() <= 0.0 {
            // A dark source: plain ray counts.
            (open, all) = by(&|_| 1.0);
        }
        let frac = |o: f32, n: f32, fallback: f32| if n > 0.0 { o / n } else { fallback };
        let overall = frac(open.iter().flatten().sum(), all.iter().flatten().sum(), 0.0);
        let side = [0, 1].map(|a| frac(open[a][0] + open[a][1], all[a][0] + all[a][1], overall));
        let pair = [0, 1].map(|a| [0, 1].map(|b| frac(open[a][b], all[a][b], side[a])));
        Self { overall, pair }
    }
}

/// `pts`: room for the receiver points, reused from link to link.
fn transfer(
    h: &Hierarchy,
    r: u32,
    s: u32,
    vis: &Visibility,
    spread: Spread,
    pts: &mut Vec<Vec3>,
) -> Transfer {
    let (nr, ns) = (h.node(r), h.node(s));
    if nr.cluster || ns.cluster {
        let dir = (ns.extent.centroid - nr.extent.centroid).normalize_or_zero();
        // The kernel at the centres, made the average over the ends.
        let (mean, _) = kernel(ends(nr, ns));
        let f = |n: &Node| if n.flat { n.normal.dot(dir).abs() } else { 1.0 };
        return Transfer::Point {
            dir,
            g: mean / (f(nr) * f(ns)).max(1e-6),
            vis: vis.overall,
        };
    }
    // Close pairs vary fast over the receiver: average over more points.
    let near = nr.center.distance(ns.center) < 2.0 * (nr.radius + ns.radius);
    pts.clear();
    receiver_points(nr.tri, if near { 2 } else { 1 }, pts);
    let sn = ns.normal;
    let mut f = [[0.0f32; 2]; 2];
    for xs in pts.chunks_exact(4) {
        let xs: [Vec3; 4] = xs.try_into().expect("chunks of four");
        for (x, sides) in xs
            .into_iter()
            .zip(points_to_triangle_sides(xs, nr.normal, ns.tri))
        {
            // x sees the source's front when it lies in front of its plane.
            let b = usize::from((x - ns.tri[0]).dot(sn) < 0.0);
            f[0][b] += sides[0];
            f[1][b] += sides[1];
        }
    }
    let w = 1.0 / pts.len() as f32;
    Transfer::Surfaces {
        f: f.map(|row| row.map(|v| v * w)),
        vis: vis.pair,
        spread,
    }
}

/// The j-th of n shadow rays between a point of `r` and a point of `s`,
/// ending just short of `s` so that neither end counts as a blocker, with
/// the source leaf it reaches and the sides it joins (not yet traced).
fn shadow_ray(h: &Hierarchy, r: u32, s: u32, seed: u32, j: usize, n: usize) -> (Ray, Sample) {
    let (pr, nr, _) = sample_point(h, r, seed, j, n, false);
    let (ps, ns, leaf) = sample_point(h, s, seed ^ 0x9e37_79b9, j, n, true);
    let mut a = offset_origin(pr, nr, ps - pr);
    let b = offset_origin(ps, ns, pr - ps);
    // A receiving cluster's directional model already keeps light from the
    // surfaces that face away (its cosines), so a ray to it counts only
    // what lies outside it: from a far point of a ball, a ray through the
    // ball itself would darken the side that faces the light a second time.
    // (The source end keeps its rays whole: a cluster's intensity counts the
    // inner sides of closed objects too, and only their blocked rays keep
    // that light in; clipped there, the transport gained energy and failed
    // to converge.)
    let rn = h.node(r);
    if rn.cluster && !rn.flat {
        let d = b - a;
        if let Some([_, out]) = sphere_span(a, d, rn.center, rn.radius) {
            a += d * out.clamp(0.0, 1.0);
        }
    }
    let sample = Sample {
        leaf,
        sides: (
            u8::from((ps - pr).dot(nr) < 0.0),
            u8::from((pr - ps).dot(ns) < 0.0),
        ),
        pass: 0,
        buried: false,
    };
    (Ray::segment(a, b - a, 1.0), sample)
}

/// The probe that tells whether a blocked shadow ray's source end lies in
/// a contact shadow: a segment from that end back towards the receiver,
/// `CONTACT` times the source leaf's radius long (at most half the way, so
/// that a touching receiver is not its own blocker).
fn buried_probe(h: &Hierarchy, ray: &Ray, leaf: u32) -> Option<Ray> {
    if leaf == NONE {
        return None;
    }
    let end = ray.origin + ray.dir * ray.tmax;
    let len = ray.dir.length() * ray.tmax;
    let l = (CONTACT * h.node(leaf).radius).min(0.5 * len);
    // Also refuses NaN lengths from a degenerate ray.
    (l > 0.0).then(|| Ray::segment(end, -ray.dir / ray.dir.length(), l))
}

/// Points per leaf side for [`open_shares`].
const OPEN_POINTS: u32 = 16;

/// The share of each leaf side (`[front, back]`) that is open, and the
/// probes traced. A point is buried when a probe along the side's normal,
/// [`CONTACT`] times the leaf's radius long, is blocked: the point lies
/// under something closer than the leaf can resolve (the wall behind a
/// chair rail, the floor under a closed box standing on it). A point in a room's
/// corner or beside a box looks out past them along its normal, and so
/// does the floor under a table higher than that reach.
///
/// A leaf's irradiance is its area average, in which a buried part counts
/// dark (its rays were blocked). That is right for the light the leaf
/// reflects, but a record stands for the surface one sees, which is never
/// buried: the records along every rail and around every box's base came
/// out dark by the buried share. They take the irradiance over the open
/// part instead.
pub fn open_shares(
    h: &Hierarchy,
    leaves: &[u32],
    object_of: &(dyn Fn(u32) -> u32 + Sync),
    engine: &dyn RayEngine,
) -> (Vec<[f32; 2]>, u64) {
    let np = OPEN_POINTS as usize;
    let shares = leaves
        .par_chunks(64)
        .flat_map_iter(|chunk| {
            let mut probes = Vec::with_capacity(chunk.len() * 2 * np);
            for &l in chunk {
                let node = h.node(l);
                let [p0, p1, p2] = node.tri;
                let reach = CONTACT * node.radius;
                for side in 0..2u32 {
                    let m = if side == 0 { node.normal } else { -node.normal };
                    for j in 0..OPEN_POINTS {
                        let hash = |c: u32| unit(hash3(l, j, c + 2 * side));
                        let (mut u, mut v) = ((j as f32 + hash(0)) / np as f32, hash(1));
                        if u + v > 1.0 {
                            (u, v) = (1.0 - u, 1.0 - v);
                        }
                        let p = p0 + (p1 - p0) * u + (p2 - p0) * v;
                        probes.push(Ray::segment(offset_origin(p, m, m), m, reach));
                    }
                }
            }
            let mut hits = vec![None; probes.len()];
            engine.intersect_batch(&probes, &mut hits);
            hits.chunks_exact(2 * np)
                .zip(chunk)
                .map(|(leaf, &l)| {
                    let own = object_of(h.node(l).patch);
                    // A coarsened patch partly inside its own object (a
                    // chord of a ball) is not buried: its links' rays start
                    // outside the object or are clipped there, so its
                    // irradiance is already that of the open surface.
                    let blocked = |hit: &Option<Hit>| hit.is_some_and(|hit| hit.object != own);
                    [0, 1].map(|side| {
                        let buried = leaf[side * np..(side + 1) * np]
                            .iter()
                            .filter(|h| blocked(h))
                            .count();
                        // A wholly buried side keeps its (dark) average.
                        if buried == np {
                            1.0
                        } else {
                            1.0 - buried as f32 / np as f32
                        }
                    })
                })
                .collect::<Vec<_>>()
        })
        .collect();
    (shares, (leaves.len() * 2 * np) as u64)
}

/// Where the line `o + t d` is inside the sphere, as `[t_in, t_out]`.
fn sphere_span(o: Vec3, d: Vec3, center: Vec3, radius: f32) -> Option<[f32; 2]> {
    let (a, oc) = (d.length_squared(), o - center);
    let b = oc.dot(d);
    let disc = b * b - a * (oc.length_squared() - radius * radius);
    (a > 0.0 && disc >= 0.0).then(|| {
        let r = disc.sqrt();
        [(-b - r) / a, (-b + r) / a]
    })
}

/// A point on the surface of node `i`, the normal there and, if `leaf`,
/// the leaf that holds it (`NONE` otherwise: only the source end's leaf
/// weighs a ray): stratified over a triangle, or on an area-chosen patch
/// of a cluster.
// Called twice a shadow ray: left out of line (as the compiler chose once the
// form factors took four points at a time), the solve took 7% longer.
#[inline(always)]
fn sample_point(
    h: &Hierarchy,
    mut i: u32,
    seed: u32,
    j: usize,
    n: usize,
    leaf: bool,
) -> (Vec3, Vec3, u32) {
    let mut u = (j as f32 + unit(hash3(seed, j as u32, 1))) / n as f32;
    if h.node(i).cluster {
        (i, u) = h.surface_at(i, u);
    }
    let node = h.node(i);
    let (mut a, mut b) = (u, unit(hash3(seed, j as u32, 2)));
    if a + b > 1.0 {
        (a, b) = (1.0 - a, 1.0 - b);
    }
    let [p0, p1, p2] = node.tri;
    let p = p0 + (p1 - p0) * a + (p2 - p0) * b;
    let at = if leaf {
        leaf_at(h, i, [1.0 - a - b, a, b])
    } else {
        NONE
    };
    (p, node.normal, at)
}

/// The leaf below surface node `i` that holds the point of barycentric
/// coordinates `w` (against `i`'s corners), following the midpoint
/// subdivision: child `k` keeps corner `k`, child 3 is the middle one.
fn leaf_at(h: &Hierarchy, mut i: u32, mut w: [f32; 3]) -> u32 {
    while let [c0, c1, c2, c3] = h.node(i).children[..] {
        (i, w) = if w[0] >= 0.5 {
            (c0, [2.0 * w[0] - 1.0, 2.0 * w[1], 2.0 * w[2]])
        } else if w[1] >= 0.5 {
            (c1, [2.0 * w[0], 2.0 * w[1] - 1.0, 2.0 * w[2]])
        } else if w[2] >= 0.5 {
            (c2, [2.0 * w[0], 2.0 * w[1], 2.0 * w[2] - 1.0])
        } else {
            // The middle child's corners are the midpoints (b+c, c+a, a+b)/2.
            (c3, [1.0 - 2.0 * w[0], 1.0 - 2.0 * w[1], 1.0 - 2.0 * w[2]])
        };
    }
    i
}

pub fn hash3(a: u32, b: u32, c: u32) -> u32 {
    let mut x = a
        .wrapping_mul(0x8da6_b343)
        .wrapping_add(b.wrapping_mul(0xd816_3841))
        .wrapping_add(c.wrapping_mul(0xcb1a_b31f));
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

/// A number in [0, 1) from a hash.
pub fn unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}
