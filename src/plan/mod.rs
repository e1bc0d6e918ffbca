//! Where and when base range images are rendered (paper §4.1, §4.2): id-images
//! and their fitness, base views by adaptive subdivision of the view space,
//! and time lists from the lights and from each base view.
//!
//! A [`Plan`] is plain data, written as JSON by `rangewalk plan` and stored in
//! every bake's manifest, so a bake can be checked against the plan it was
//! made from. The method, its defaults and measured plans are described in
//! `docs/plan.md`.

use std::collections::{BTreeSet, HashMap};
use std::path::Path;
use std::time::Instant;

use anyhow::{ensure, Context, Result};
use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::accel::{InstancedEngine, RayEngine};
use crate::quality::Quality;
use crate::scene::Scene;

pub mod coverage;
pub mod idimage;
pub mod lights;
pub mod times;
pub mod views;

pub use idimage::{fitness, IdImage, IdView, Parallel};
pub use times::{Frames, IntervalTest};
pub use views::CellTest;

/// The base views of a scene and the times each is rendered at.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// The quality `q` every subdivision followed.
    pub quality: Quality,
    /// Base views in a fixed order (bakes name images by view index).
    pub views: Vec<PlannedView>,
    /// The times direct light needs (from the lights' id-images), before
    /// any per-view refinement.
    pub light_times: Vec<f32>,
    /// Every planning step with the time it took.
    pub steps: Vec<Step>,
    /// What was left out and why (a static scene gets one time, ...).
    pub skipped: Vec<String>,
    /// Side of the square id-images every fitness was measured on.
    #[serde(default)]
    pub resolution: u32,
    /// Whether every view got the union of all views' lists (the paper's
    /// one master list) instead of its own.
    #[serde(default)]
    pub master_list: bool,
    /// The cameras direct light was judged from.
    #[serde(default)]
    pub lights: Vec<String>,
    /// What the cells' fitness measured.
    #[serde(default)]
    pub view_fitness: ViewFitness,
    /// The view-space cells tested, in the order tested.
    #[serde(default)]
    pub cells: Vec<CellTest>,
    /// The time intervals tested: the lights' list, then each view's.
    #[serde(default)]
    pub intervals: Vec<IntervalTest>,
}

/// One base viewpoint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlannedView {
    pub position: Vec3,
    /// Strictly increasing scene times (s) of this view's base images.
    pub times: Vec<f32>,
}

/// One planning step and what it cost.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Step {
    pub name: String,
    pub seconds: f64,
    /// Id-images the step rendered.
    #[serde(default)]
    pub id_images: usize,
}

/// What to plan for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanOptions {
    pub quality: Quality,
    /// Side of the square id-images; [`default_resolution`] when `None`.
    pub resolution: Option<u32>,
    /// One master list for all views (the paper's choice) instead of a
    /// list per view.
    pub master_list: bool,
    /// What a view-space cell's fitness measures.
    pub view_fitness: ViewFitness,
}

/// What decides whether a view-space cell is split.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    Serialize,
    Deserialize,
    strum::Display,
    strum::EnumString,
    strum::IntoStaticStr,
    strum::VariantArray,
    strum::EnumMessage,
)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum ViewFitness {
    /// The fraction of directions in which every corner sees the same object (the paper's).
    #[default]
    Ids,
    /// The fraction of the surfaces seen from the cell's centre that every corner sees (beyond the paper): what its bases do not see, a frame inside the cell cannot show.
    Coverage,
}

/// Smallest and largest id-image side accepted.
pub const RESOLUTIONS: std::ops::RangeInclusive<u32> = 4..=4096;

/// Id-image side for a quality: `64 · 4^q` rounded to a multiple of 16,
/// from 64 at q = 0 to 256 at q = 1 (96, 144, 224 at 0.3, 0.6, 0.9). A
/// higher quality asks for a finer fitness; `docs/plan.md` measures how
/// fitness converges with the side.
pub fn default_resolution(q: Quality) -> u32 {
    let side = 64.0 * 4f32.powf(q.get());
    16 * (side / 16.0).round() as u32
}

/// Plans base views and their times for `scene`. `engine` must hold
/// `scene.geometry()`; planning poses it with `scene.at(t)` at every time
/// it needs and leaves it posed at the last one, so a caller that traces
/// afterwards poses it again.
pub fn make(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    options: &PlanOptions,
) -> Result<Plan> {
    let q = options.quality.get();
    let size = match options.resolution {
        Some(n) => {
            ensure!(
                RESOLUTIONS.contains(&n),
                "id-image resolution {n} is outside [{}, {}]",
                RESOLUTIONS.start(),
                RESOLUTIONS.end()
            );
            n
        }
        None => default_resolution(options.quality),
    };
    let frames = Frames::new(scene.animation);
    let mut skipped = Vec::new();
    let mut steps = Vec::new();
    let animated = if scene.is_static() {
        skipped.push(format!(
            "static scene: one time (the start, t = {}), no id-images over time",
            frames.time(0)
        ));
        false
    } else if frames.last == 0 {
        skipped.push(format!(
            "the animation has no duration (start = end = {}): one time, no id-images over time",
            frames.time(0)
        ));
        false
    } else {
        true
    };
    let moving: Vec<bool> = scene
        .objects
        .iter()
        .map(|o| !o.motion.is_static())
        .collect();

    let clock = Instant::now();
    let light = if animated {
        light_list(scene, engine, &frames, q, size, &moving, &mut skipped)?
    } else {
        LightList {
            frames: vec![0],
            tests: Vec::new(),
            labels: Vec::new(),
            images: 0,
        }
    };
    steps.push(Step {
        name: "light time list".into(),
        seconds: clock.elapsed().as_secs_f64(),
        id_images: light.images,
    });

    let clock = Instant::now();
    let mut tested: BTreeSet<u32> = light.frames.iter().copied().collect();
    if animated {
        tested.extend([0, frames.last]);
    }
    let tested: Vec<u32> = tested.into_iter().collect();
    let times: Vec<f32> = tested.iter().map(|&k| frames.time(k)).collect();
    let (positions, cells, images) = match &scene.view_space {
        Some(space) => {
            let s = views::subdivide(
                scene,
                engine,
                space,
                &times,
                (q, options.view_fitness),
                size,
            )?;
            if q == 0.0 {
                skipped.push(
                    "quality 0: the view space's corners, no id-images for base views".into(),
                );
            }
            (s.positions, s.cells, s.images)
        }
        None => {
            let camera = scene.cameras.first().with_context(|| {
                format!(
                    "{}: no [view_space] and no [[cameras]]: nowhere to place a base view",
                    scene.source.display()
                )
            })?;
            skipped.push(format!(
                "no view space in {}: one base view at camera `{}`'s position {}",
                scene.source.display(),
                camera.name,
                camera.position
            ));
            (vec![camera.position], Vec::new(), 0)
        }
    };
    steps.push(Step {
        name: "base views".into(),
        seconds: clock.elapsed().as_secs_f64(),
        id_images: images,
    });

    let clock = Instant::now();
    let mut intervals = light.tests;
    let (lists, images) = if animated {
        let render = |e: &dyn RayEngine, v: usize, _: f32| -> Result<Vec<IdImage>> {
            let camera = views::sphere(positions[v], size)?;
            Ok(vec![idimage::render(e, &IdView::Camera(camera))])
        };
        let b = times::bisect(
            scene,
            engine,
            &frames,
            q,
            vec![tested.clone(); positions.len()],
            HashMap::new(),
            &render,
            &moving,
            Some,
        )?;
        intervals.extend(b.tests);
        let lists = b
            .frames
            .into_iter()
            .zip(&b.saw)
            .enumerate()
            .map(|(v, (list, &saw))| {
                if saw {
                    list
                } else {
                    skipped.push(format!(
                        "view {v} at {}: no moving object visible at the times tested; keeps the light list",
                        positions[v]
                    ));
                    light.frames.clone()
                }
            })
            .collect();
        (lists, b.images)
    } else {
        (vec![vec![0]; positions.len()], 0)
    };
    let lists: Vec<Vec<u32>> = if options.master_list {
        let all: BTreeSet<u32> = lists.iter().flatten().copied().collect();
        vec![all.into_iter().collect(); positions.len()]
    } else {
        lists
    };
    steps.push(Step {
        name: "view time lists".into(),
        seconds: clock.elapsed().as_secs_f64(),
        id_images: images,
    });

    let to_times = |l: &[u32]| l.iter().map(|&k| frames.time(k)).collect::<Vec<f32>>();
    Ok(Plan {
        quality: options.quality,
        views: positions
            .iter()
            .zip(&lists)
            .map(|(&position, l)| PlannedView {
                position,
                times: to_times(l),
            })
            .collect(),
        light_times: to_times(&light.frames),
        steps,
        skipped,
        resolution: size,
        master_list: options.master_list,
        lights: light.labels,
        view_fitness: options.view_fitness,
        cells,
        intervals,
    })
}

struct LightList {
    frames: Vec<u32>,
    tests: Vec<IntervalTest>,
    labels: Vec<String>,
    images: usize,
}

/// The lights' time list: bisection of the animation on the id-images of
/// every light probe that a moving object can change.
fn light_list(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    frames: &Frames,
    q: f32,
    size: u32,
    moving: &[bool],
    skipped: &mut Vec<String>,
) -> Result<LightList> {
    let probes = lights::probes(scene, animation_bounds(scene, frames));
    let labels: Vec<String> = probes.iter().map(|p| p.label.clone()).collect();
    if probes.is_empty() {
        skipped.push("no lights and no emitting objects: direct light adds no times".into());
        return Ok(LightList {
            frames: vec![0],
            tests: Vec::new(),
            labels,
            images: 0,
        });
    }
    let shoot = |e: &dyn RayEngine, which: &[usize], t: f32| -> Result<Vec<IdImage>> {
        which
            .iter()
            .map(|&i| Ok(idimage::render(e, &probes[i].view(scene, t, size)?)))
            .collect()
    };
    let all: Vec<usize> = (0..probes.len()).collect();
    let mut ends = Vec::new();
    for k in [0, frames.last] {
        let t = frames.time(k);
        engine
            .set_transforms(&scene.at(t))
            .with_context(|| format!("posing the scene at t = {t}"))?;
        ends.push(shoot(&*engine, &all, t)?);
    }
    let mut images = 2 * probes.len();
    let active: Vec<usize> = all
        .iter()
        .copied()
        .filter(|&i| {
            let changes =
                probes[i].moves || ends[0][i].sees_any(moving) || ends[1][i].sees_any(moving);
            if !changes {
                skipped.push(format!(
                    "{}: no moving object in its id-images at t = {} and {}; adds no times",
                    probes[i].label,
                    frames.time(0),
                    frames.time(frames.last)
                ));
            }
            changes
        })
        .collect();
    if active.is_empty() {
        skipped.push(
            "direct light does not change (no light sees a moving object): the light list is the start alone"
                .into(),
        );
        return Ok(LightList {
            frames: vec![0],
            tests: Vec::new(),
            labels,
            images,
        });
    }
    let pick = |ims: &[IdImage]| active.iter().map(|&i| ims[i].clone()).collect::<Vec<_>>();
    let seed = HashMap::from([((0, 0), pick(&ends[0])), ((0, frames.last), pick(&ends[1]))]);
    let render = |e: &dyn RayEngine, _: usize, t: f32| shoot(e, &active, t);
    let b = times::bisect(
        scene,
        engine,
        frames,
        q,
        vec![vec![0, frames.last]],
        seed,
        &render,
        moving,
        |_| None,
    )?;
    images += b.images;
    Ok(LightList {
        frames: b.frames.into_iter().next().unwrap_or_default(),
        tests: b.tests,
        labels,
        images,
    })
}

/// The scene's bounds over every frame, from each object's box carried by
/// its pose (cheap for long animations of large meshes).
fn animation_bounds(scene: &Scene, frames: &Frames) -> (Vec3, Vec3) {
    let boxes: Vec<(Vec3, Vec3)> = scene
        .objects
        .iter()
        .map(|o| {
            o.mesh.positions.iter().fold(
                (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
                |(lo, hi), &p| (lo.min(p), hi.max(p)),
            )
        })
        .collect();
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for k in 0..=frames.last {
        for (o, &(blo, bhi)) in scene.objects.iter().zip(&boxes) {
            if blo.x > bhi.x {
                continue;
            }
            let pose = o.motion.pose(frames.time(k));
            for c in 0..8 {
                let corner = Vec3::new(
                    if c & 1 == 0 { blo.x } else { bhi.x },
                    if c & 2 == 0 { blo.y } else { bhi.y },
                    if c & 4 == 0 { blo.z } else { bhi.z },
                );
                let w = pose.transform_point3(corner);
                lo = lo.min(w);
                hi = hi.max(w);
            }
        }
    }
    (lo, hi)
}

impl Plan {
    /// Writes the plan as JSON through a temporary file renamed into place,
    /// so an interrupted write never leaves a partial plan under `path`.
    pub fn save(&self, path: &Path) -> Result<()> {
        let json = serde_json::to_string_pretty(self).context("serializing the plan")?;
        crate::output::write_file(path, json + "\n")
    }

    /// Reads a plan written by [`Plan::save`].
    pub fn load(path: &Path) -> Result<Plan> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        serde_json::from_str(&text).with_context(|| format!("{}: not a plan", path.display()))
    }
}
