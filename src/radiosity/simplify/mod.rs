//! Geometric simplification for the radiosity solver (paper §4.3).
//!
//! Radiosity cost grows with the square of the patch count, while indirect
//! light is smooth: a scene of tens of thousands of triangles is reduced to
//! a few thousand patches of about one size. Two criteria decide, both
//! driven by the quality `q` (see [`Params`] and `docs/simplification.md`):
//!
//! - *visibility*: rays from random viewpoints of the view space at random
//!   times count hits per object; rarely hit objects are left out, moderately
//!   hit ones coarsened further, frequently hit ones kept;
//! - *area*: connected parts smaller than a patch or two are pruned, objects
//!   whose triangles are smaller than a patch are coarsened with meshopt,
//!   and every kept triangle is bisected down to a maximum edge length.
//!
//! Emitters are never left out or coarsened, so the emitted power stays
//! exact. Left-out objects and pruned parts still stand in the light: the
//! solver traces visibility in the full scene, and lets rays through what
//! was left out with its albedo's share (see [`Simplified::pruned`]).

use std::time::Instant;

use anyhow::{ensure, Context, Result};
use glam::Vec3;

use super::{Quality, Simplified, SimplifyStats};
use crate::accel::InstancedEngine;
use crate::scene::{Mesh, Scene};

mod coarsen;
mod params;
mod parts;
mod tessellate;
mod visibility;

pub use coarsen::{AREA_TOLERANCE, ERROR as COARSEN_ERROR};
pub use params::Params;

/// How often the visibility rays hit an object.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Seen {
    Rarely,
    Moderately,
    Frequently,
}

/// What became of an object.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fate {
    /// Left out: (almost) never seen from the view space.
    Unseen,
    /// Left out: every connected part is smaller than
    /// [`Params::min_part_area`].
    Small,
    /// Reduced with meshopt (its area then within [`AREA_TOLERANCE`]), then
    /// bisected.
    Coarsened,
    /// Every input triangle kept, then bisected: the area is exact.
    Whole,
}

/// One object's part in the simplification.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectReport {
    pub hits: u64,
    pub seen: Seen,
    pub fate: Fate,
    pub input_triangles: usize,
    /// Triangles left after pruning and coarsening, before bisection.
    pub kept_triangles: usize,
    /// Object-space area of the connected parts pruned as smaller than
    /// [`Params::min_part_area`] (the rest of a kept object keeps its area).
    pub pruned_area: f32,
    pub pruned_parts: usize,
    pub patches: usize,
}

/// The simplified scene with the decisions that made it, for reports.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    pub simplified: Simplified,
    pub params: Params,
    /// In object order.
    pub objects: Vec<ObjectReport>,
    /// Patches whose bisection the depth guard stopped with an edge still
    /// longer than `params.max_edge`.
    pub depth_limited: usize,
}

/// Simplifies `scene` for radiosity at `quality`. `engine` holds the full
/// scene; it is moved to random times to measure visibility from the view
/// space and is left posed at the scene's start time (a solve that went on
/// with the last random pose saw the boxes of the Cornell box where they
/// were not, and the records beside them came out a third too dark).
pub fn simplify(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    quality: Quality,
) -> Result<Simplified> {
    Ok(simplify_report(scene, engine, quality)?.simplified)
}

/// [`simplify`], telling what happened to each object.
///
/// Without a view space the scene's cameras are the viewpoints (rays in a
/// wide cone around each camera's direction); without either, visibility
/// cannot be measured and every object counts as frequently seen.
pub fn simplify_report(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    quality: Quality,
) -> Result<Report> {
    let clock = Instant::now();
    let file = scene.source.display();
    let initial: usize = scene.objects.iter().map(|o| o.mesh.triangles.len()).sum();
    ensure!(
        initial > 0,
        "{file}: the scene has no triangles to simplify"
    );
    let start = scene.animation.start;
    let (lo, hi) = scene.bounds(start);
    let size = (hi - lo).length();
    ensure!(
        size.is_finite() && size > 0.0,
        "{file}: the scene's bounds {lo}..{hi} at t = {start} have no usable size"
    );
    let params = Params::new(quality, size);
    let counts = visibility::count_hits(scene, engine, params.visibility_rays)?;
    let total_hits: u64 = counts.as_ref().map_or(0, |c| c.hits.iter().sum());
    let poses = scene.at(start);
    engine
        .set_transforms(&poses)
        .with_context(|| format!("{file}: posing the scene at t = {start}"))?;

    let mut objects = Vec::with_capacity(scene.objects.len());
    let mut pieces: Vec<(u32, [Vec3; 3])> = Vec::new();
    let mut pruned = Vec::new();
    let mut depth_limited = 0;
    for (i, o) in scene.objects.iter().enumerate() {
        let emitter = scene.materials[o.material].emission.is_some();
        let hits = counts.as_ref().map_or(0, |c| c.hits[i]);
        let seen = match &counts {
            None => Seen::Frequently,
            Some(_) => classify(hits, total_hits, &params),
        };
        // Sizes are compared in world units; the mesh is in object space.
        let scale = poses[i].matrix3.x_axis.length();
        let scale = if scale.is_finite() && scale > 0.0 {
            scale
        } else {
            1.0
        };
        let r = if emitter {
            Reduced {
                fate: Fate::Whole,
                kept: triangles(&o.mesh),
                pruned: Vec::new(),
                pruned_area: 0.0,
                pruned_parts: 0,
            }
        } else {
            reduce(&o.mesh, seen, scale, &params)
        };
        let mut split = Vec::new();
        for &t in &r.kept {
            split.clear();
            let (edge, area) = (
                params.max_edge / scale,
                params.min_patch_area / (scale * scale),
            );
            if tessellate::bisect(t, edge, area, params.max_depth, &mut split) {
                depth_limited += 1;
            }
            pieces.extend(split.iter().map(|&p| (i as u32, p)));
        }
        objects.push(ObjectReport {
            hits,
            seen,
            fate: r.fate,
            input_triangles: o.mesh.triangles.len(),
            kept_triangles: r.kept.len(),
            pruned_area: r.pruned_area,
            pruned_parts: r.pruned_parts,
            patches: 0,
        });
        pruned.extend(r.pruned.iter().map(|&t| (i as u32, t)));
    }

    let mut simplified = Simplified::from_triangles(scene, pieces);
    simplified.pruned = pruned;
    for p in &simplified.patches {
        objects[p.object as usize].patches += 1;
    }
    ensure!(
        !simplified.patches.is_empty(),
        "{file}: nothing is left for radiosity at quality {}: all {initial} triangles were pruned \
         (no object was hit from the view space or the cameras, and none emits)",
        quality.get()
    );
    let kept: usize = objects.iter().map(|r| r.kept_triangles).sum();
    simplified.stats = SimplifyStats {
        initial_surfaces: initial,
        pruned_surfaces: initial - kept,
        final_surfaces: simplified.patches.len(),
        visibility_rays: counts.as_ref().map_or(0, |c| c.rays),
        seconds: clock.elapsed().as_secs_f64(),
    };
    Ok(Report {
        simplified,
        params,
        objects,
        depth_limited,
    })
}

fn classify(hits: u64, total_hits: u64, params: &Params) -> Seen {
    let share = if total_hits == 0 {
        0.0
    } else {
        hits as f64 / total_hits as f64
    };
    if hits == 0 || share < params.rare_share {
        Seen::Rarely
    } else if share < params.moderate_share {
        Seen::Moderately
    } else {
        Seen::Frequently
    }
}

/// What is left of one object before bisection.
struct Reduced {
    fate: Fate,
    kept: Vec<[Vec3; 3]>,
    /// The input triangles left out, ascending.
    pruned: Vec<u32>,
    pruned_area: f32,
    pruned_parts: usize,
}

/// Applies the visibility class and the area criterion to a non-emitter:
/// left out when rarely seen, small parts pruned, coarsened to about one
/// triangle per patch area (fewer when only moderately seen).
fn reduce(mesh: &Mesh, seen: Seen, scale: f32, params: &Params) -> Reduced {
    if seen == Seen::Rarely {
        return Reduced {
            fate: Fate::Unseen,
            kept: Vec::new(),
            pruned: (0..mesh.triangles.len() as u32).collect(),
            pruned_area: 0.0,
            pruned_parts: 0,
        };
    }
    let min_area = params.min_part_area / (scale * scale);
    let parts::Pruned {
        kept: mesh,
        triangles: pruned,
        area: pruned_area,
        parts: pruned_parts,
    } = parts::prune_small(mesh, min_area);
    let keep = if seen == Seen::Moderately {
        params.moderate_keep
    } else {
        1.0
    };
    let budget = mesh.area() * scale * scale / params.patch_area * keep;
    let budget = budget.ceil().max(1.0) as usize;
    let (fate, kept) = if mesh.triangles.is_empty() {
        (Fate::Small, Vec::new())
    } else if budget >= mesh.triangles.len() {
        (Fate::Whole, triangles(&mesh))
    } else {
        match coarsen::coarsen(&mesh, budget) {
            Some(c) => (Fate::Coarsened, c),
            None => (Fate::Whole, triangles(&mesh)),
        }
    };
    Reduced {
        fate,
        kept,
        pruned,
        pruned_area,
        pruned_parts,
    }
}

/// The non-degenerate triangles of `mesh`.
fn triangles(mesh: &Mesh) -> Vec<[Vec3; 3]> {
    mesh.triangles
        .iter()
        .map(|t| t.map(|v| mesh.positions[v as usize]))
        .filter(nondegenerate)
        .collect()
}

/// The test `from_triangles` applies, so that kept triangles become patches.
pub(super) fn nondegenerate(t: &[Vec3; 3]) -> bool {
    let c = (t[1] - t[0]).cross(t[2] - t[0]);
    c.length() > 0.0 && c.normalize_or_zero() != Vec3::ZERO
}
