//! Hierarchical radiosity on the simplified scene.
//!
//! The unknown is the *reflected* radiosity `B_r = ρ (D + K B_r)`: emitted
//! light and the lights that are not surfaces enter only through the direct
//! irradiance `D`, so that indirect irradiance `K B_r` is what the records
//! carry and direct light stays with the renderer's shadow rays.
//!
//! Refinement starts from the root cluster's self link (Smits, Arvo &
//! Greenberg 1994; Sillion 1995) and splits links whose error estimate
//! exceeds a fraction of the scene's power, down to surface elements of a
//! minimum area; solving and refining alternate for a few rounds, each
//! round weighing links with the radiosity of the previous one.

use std::time::Instant;

use anyhow::{bail, Context, Result};
use glam::Vec3;

use super::{IndirectSolution, Quality, Simplified, SolveStats};
use crate::accel::RayEngine;
use crate::scene::{Light, Scene};

mod extent;
mod hierarchy;
mod linear;
mod links;
mod output;
mod pruned;
mod sources;
mod standin;

use hierarchy::{Hierarchy, NONE};
use linear::{Field, Operator};
use links::{Link, Refiner, Sample};

/// What a quality `q` asks of the solver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    /// A link's error estimate may reach this fraction of the scene's power
    /// (emitted plus reflected).
    pub link_error: f32,
    /// Surface elements are not split below this fraction of the total
    /// patch area.
    pub min_area_fraction: f32,
    /// Shadow rays per link for its visible fraction.
    pub rays_per_link: usize,
    /// Direct light from point lights and the sun is sampled on a
    /// `direct_grid × direct_grid` stratified grid of points per element.
    pub direct_grid: usize,
    /// Solve-and-refine rounds.
    pub rounds: usize,
    /// Relative residual the linear solver stops at.
    pub tolerance: f64,
    /// The same for the rounds before the last, whose solutions only guide
    /// refinement.
    pub oracle_tolerance: f64,
    pub max_iterations: usize,
}

impl Params {
    pub fn new(quality: Quality) -> Self {
        let q = quality.get();
        Self {
            link_error: 10f32.powf(-(3.2 + 5.0 * q / 3.0)),
            min_area_fraction: 10f32.powf(-(1.5 + 3.0 * q)),
            rays_per_link: 4 + (4.0 * q).round() as usize,
            direct_grid: 5 + (3.0 * q).round() as usize,
            rounds: if q < 0.5 { 2 } else { 3 },
            tolerance: 1e-5,
            oracle_tolerance: 1e-3,
            max_iterations: 500,
        }
    }
}

/// Indirect irradiance at every record of `simplified` at `time`. `engine`
/// holds the full scene posed at `time` (occluders include what the
/// simplification left out).
pub fn solve(
    scene: &Scene,
    simplified: &Simplified,
    engine: &dyn RayEngine,
    time: f32,
    quality: Quality,
) -> Result<IndirectSolution> {
    solve_posing(
        scene,
        simplified,
        engine,
        time,
        quality,
        &mut Engines::default(),
    )
}

/// The ray engines a solve builds for itself over the scene's kept and
/// left-out triangles, kept from one solve to the next of one scene,
/// simplification and backend (a temporal decomposition), which re-pose
/// them rather than build them again.
#[derive(Default)]
pub struct Engines {
    pruned: Option<pruned::Pruned>,
}

/// [`solve`] with the engines of earlier solves of the same scene and
/// simplification (built on first use).
pub fn solve_posing(
    scene: &Scene,
    simplified: &Simplified,
    engine: &dyn RayEngine,
    time: f32,
    quality: Quality,
    engines: &mut Engines,
) -> Result<IndirectSolution> {
    let start = Instant::now();
    validate(scene, simplified)?;
    let params = Params::new(quality);
    let total_area: f32 = simplified.patches.iter().map(|p| p.area()).sum();
    let poses = scene.at(time);
    let lifts = standin::lifts(scene, simplified, &poses, engine);
    let pruned = match &mut engines.pruned {
        Some(pruned) => {
            pruned.pose(&poses)?;
            pruned
        }
        None => engines.pruned.insert(pruned::Pruned::new(
            scene,
            simplified,
            engine.backend(),
            &poses,
        )?),
    };
    let mut h = Hierarchy::build(
        simplified,
        &poses,
        &lifts,
        total_area * params.min_area_fraction,
    );
    let zero = vec![Vec3::ZERO; simplified.records.len()];
    let mut stats = SolveStats::default();
    let empty = |stats: SolveStats| IndirectSolution {
        time,
        indirect: zero.clone(),
        direct: zero.clone(),
        stats: SolveStats {
            seconds: start.elapsed().as_secs_f64(),
            ..stats
        },
    };
    if h.root == NONE {
        return Ok(empty(stats));
    }

    // Direct irradiance from point lights and the sun, per node as nodes
    // appear (inner nodes too: the oracle weighs them).
    let mut direct_nodes: Vec<[Vec3; 2]> = Vec::new();
    let mut links: Vec<Link> = Vec::new();
    let mut samples: Vec<Sample> = Vec::new();
    // Reflected radiosity per leaf, from the last solve.
    let mut solution: Option<Field> = None;
    for round in 0..params.rounds {
        stats.shadow_rays += extend_direct(&h, &mut direct_nodes, &scene.lights, engine, &params);
        let old_leaves = h.leaves();
        let oracle = {
            let op = Operator::new(&h, Vec::new());
            let src: Field = op
                .leaves
                .iter()
                .enumerate()
                .map(|(k, &l)| {
                    let p = h.node(l).patch as usize;
                    let e = h.emission[p];
                    let r = match &solution {
                        Some(x) => x[k],
                        None => direct_nodes[l as usize].map(|d| d * h.reflectance[p]),
                    };
                    [e[0] + r[0], e[1] + r[1]]
                })
                .collect();
            op.pull(&src)
        };
        let scene_power = oracle.p[h.root as usize].max_element();
        if scene_power == 0.0 {
            return Ok(empty(stats));
        }
        if !(scene_power > 0.0 && scene_power.is_finite()) {
            bail!(
                "radiosity at t = {time}: the solution diverged (scene power {scene_power}); \
                 the transport operator gains energy somewhere"
            );
        }
        let mut refiner = Refiner {
            radiosity: &oracle,
            max_error: params.link_error * scene_power,
            pending: Vec::new(),
        };
        if round == 0 {
            let root = h.root;
            refiner.refine(&mut h, vec![(root, root)]);
        } else {
            let mut split = refiner.to_split(&h, &links).into_iter();
            let mut pairs = Vec::new();
            // In place: a new list of the kept links would be tens of
            // megabytes of fresh memory a round.
            links.retain(|l| {
                let split = split.next().expect("a verdict per link");
                if split {
                    pairs.extend(refiner.split_link(&mut h, l.r, l.s));
                }
                !split
            });
            refiner.refine(&mut h, pairs);
        }
        let pending = std::mem::take(&mut refiner.pending);
        let weight = |leaf: u32, side: usize| refiner.weight(&h, leaf, side);
        links::reweigh(&mut links, &samples, params.rays_per_link, &weight);
        let (new, rays) = links::compute(
            &h,
            &pending,
            engine,
            pruned,
            params.rays_per_link,
            &weight,
            &mut samples,
        );
        stats.shadow_rays += rays;
        stats.shadow_rays += extend_direct(&h, &mut direct_nodes, &scene.lights, engine, &params);

        let last = round + 1 == params.rounds;
        let mut parts = vec![std::mem::take(&mut links)];
        parts.extend(new);
        let op = Operator::new(&h, parts);
        let guess = solution
            .take()
            .map(|x| inherit(&h, &old_leaves, &x, &op.leaves))
            .unwrap_or_else(|| vec![[Vec3::ZERO; 2]; op.leaves.len()]);
        let (direct, rho) = direct_field(&h, &op, &direct_nodes);
        let b: Field = direct
            .iter()
            .zip(&rho)
            .map(|(d, &r)| [d[0] * r, d[1] * r])
            .collect();
        // Rounds before the last only weigh the oracle's next verdicts.
        let tolerance = if last {
            params.tolerance
        } else {
            params.oracle_tolerance
        };
        let solved = linear::solve(&op, &rho, &b, guess, tolerance, params.max_iterations);
        stats.iterations += solved.iterations;
        stats.residual = solved.residual;
        if last {
            // The rounds before the last stop at `oracle_tolerance`: a final
            // solution worse than theirs has not converged.
            solved
                .check(params.oracle_tolerance)
                .with_context(|| format!("at t = {time}"))?;
            let indirect = op.apply(&solved.x);
            let (open, probes) = links::open_shares(
                &h,
                &op.leaves,
                &|p| simplified.patches[p as usize].object,
                engine,
            );
            stats.shadow_rays += probes;
            let index = leaf_index(&h, &op.leaves);
            let (ind, dir) = output::records(
                simplified,
                &h,
                |l| index[l as usize],
                &indirect,
                &direct,
                &open,
            );
            stats.elements = op.leaves.len();
            stats.links = op.links().len();
            stats.seconds = start.elapsed().as_secs_f64();
            return Ok(IndirectSolution {
                time,
                indirect: ind,
                direct: dir,
                stats,
            });
        }
        solution = Some(solved.x);
        links = op.into_links();
    }
    unreachable!("the last round returns")
}

/// Direct irradiance on the leaves (emitters through the links plus point
/// lights and the sun) and the leaves' reflectances.
fn direct_field(h: &Hierarchy, op: &Operator, direct_nodes: &[[Vec3; 2]]) -> (Field, Vec<Vec3>) {
    let emission: Field = op
        .leaves
        .iter()
        .map(|&l| h.emission[h.node(l).patch as usize])
        .collect();
    let from_emitters = op.apply(&emission);
    let direct = op
        .leaves
        .iter()
        .zip(from_emitters)
        .map(|(&l, e)| {
            let d = direct_nodes[l as usize];
            [d[0] + e[0], d[1] + e[1]]
        })
        .collect();
    let rho = op
        .leaves
        .iter()
        .map(|&l| h.reflectance[h.node(l).patch as usize])
        .collect();
    (direct, rho)
}

/// Point-light and sun irradiance for the nodes created since the last
/// call; returns the shadow rays traced.
fn extend_direct(
    h: &Hierarchy,
    direct: &mut Vec<[Vec3; 2]>,
    lights: &[Light],
    engine: &dyn RayEngine,
    params: &Params,
) -> u64 {
    let new: Vec<u32> = (direct.len() as u32..h.nodes.len() as u32)
        .filter(|&i| !h.node(i).cluster)
        .collect();
    let (values, rays) = sources::direct(h, &new, lights, engine, params.direct_grid);
    direct.resize(h.nodes.len(), [Vec3::ZERO; 2]);
    for (&i, v) in new.iter().zip(values) {
        direct[i as usize] = v;
    }
    rays
}

/// Leaf number of each node (`usize::MAX` for inner nodes).
fn leaf_index(h: &Hierarchy, leaves: &[u32]) -> Vec<usize> {
    let mut index = vec![usize::MAX; h.nodes.len()];
    for (k, &l) in leaves.iter().enumerate() {
        index[l as usize] = k;
    }
    index
}

/// The previous round's leaf values carried to the new leaves: a split
/// element's children start from their parent's value.
fn inherit(h: &Hierarchy, old: &[u32], x: &Field, new: &[u32]) -> Field {
    let mut value = vec![None; h.nodes.len()];
    for (&l, v) in old.iter().zip(x) {
        value[l as usize] = Some(*v);
    }
    new.iter()
        .map(|&l| {
            let mut i = l;
            loop {
                if let Some(v) = value[i as usize] {
                    return v;
                }
                i = h.node(i).parent;
                if i == NONE {
                    return [Vec3::ZERO; 2];
                }
            }
        })
        .collect()
}

/// Reflectances must keep the system solvable and every input finite; the
/// error names the object at fault.
fn validate(scene: &Scene, s: &Simplified) -> Result<()> {
    for p in &s.patches {
        let name = scene
            .objects
            .get(p.object as usize)
            .map_or("?", |o| o.name.as_str());
        let r = p.reflectance;
        if !r.is_finite() || r.min_element() < 0.0 || r.max_element() >= 1.0 {
            bail!(
                "object `{name}`: reflectance [{}, {}, {}] (diffuse plus glossy, as radiosity carries it) must be in [0, 1) in every channel for radiosity to converge",
                r.x,
                r.y,
                r.z
            );
        }
        let e = p.emission;
        if !e.is_finite() || e.min_element() < 0.0 {
            bail!(
                "object `{name}`: emitted radiance [{}, {}, {}] must be finite and non-negative",
                e.x,
                e.y,
                e.z
            );
        }
        if !p.vertices.iter().all(|v| v.is_finite()) {
            bail!("object `{name}`: a patch has a non-finite vertex");
        }
    }
    for &(o, t) in &s.pruned {
        let Some(object) = scene.objects.get(o as usize) else {
            bail!(
                "the simplified scene lists a left-out triangle of object {o}, but the scene has {} objects",
                scene.objects.len()
            );
        };
        if t as usize >= object.mesh.triangles.len() {
            bail!(
                "object `{}`: the simplified scene lists left-out triangle {t}, but the mesh has {}",
                object.name,
                object.mesh.triangles.len()
            );
        }
    }
    for (i, l) in scene.lights.iter().enumerate() {
        let ok = match *l {
            Light::Point {
                position,
                intensity,
            } => position.is_finite() && intensity.is_finite() && intensity.min_element() >= 0.0,
            Light::Sun {
                direction,
                radiance,
                angular_diameter_deg,
            } => {
                direction.is_finite()
                    && direction != Vec3::ZERO
                    && radiance.is_finite()
                    && radiance.min_element() >= 0.0
                    && angular_diameter_deg.is_finite()
            }
        };
        if !ok {
            bail!("light {i} ({l:?}) has a non-finite or negative value");
        }
    }
    Ok(())
}
