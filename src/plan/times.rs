//! Time lists by recursive bisection on id-image fitness (paper §4.2).
//!
//! Times are frames of the animation: a base image between two frames
//! would never be shown as it is, and "one frame apart" is a natural end
//! to the bisection. Several *tracks* (the lights together; each base view
//! on its own) are bisected side by side, level by level, so that the
//! scene is posed once per frame for every track that needs that frame.

use std::collections::{BTreeMap, BTreeSet, HashMap};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};

use super::idimage::{fitness, IdImage};
use crate::accel::{InstancedEngine, RayEngine};
use crate::scene::{Animation, Scene};

/// The animation's frames: frame `k` is at `start + k / fps`, and the last
/// one at `end` even where the duration is not a whole number of frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frames {
    pub animation: Animation,
    /// Index of the frame at `end` (0 for an animation without duration).
    pub last: u32,
}

impl Frames {
    pub fn new(animation: Animation) -> Self {
        let span = (animation.end - animation.start) * animation.fps;
        // A tolerance of a thousandth of a frame keeps `end = 1, fps = 30`
        // at 30 frames despite rounding.
        let last = (span - 1e-3).ceil().max(0.0) as u32;
        Self { animation, last }
    }

    pub fn time(&self, k: u32) -> f32 {
        let a = self.animation;
        if k >= self.last {
            a.end
        } else {
            a.start + k as f32 / a.fps
        }
    }
}

/// The fitness test of one interval of a time list.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct IntervalTest {
    /// The base view whose list this is; `None` for the lights' list.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub view: Option<usize>,
    pub t0: f32,
    pub t1: f32,
    /// The lowest fitness over the track's id-images at the two ends.
    pub fitness: f32,
    /// Whether the interval was bisected (fitness below the quality and
    /// more than one frame long).
    pub split: bool,
}

/// Id-images of one track at one time (a track may have several cameras:
/// all light probes judge the lights' list together).
pub type Render<'a> = dyn Fn(&dyn RayEngine, usize, f32) -> Result<Vec<IdImage>> + 'a;

/// The result of bisecting every track.
pub struct Bisected {
    /// Each track's frames, increasing.
    pub frames: Vec<Vec<u32>>,
    pub tests: Vec<IntervalTest>,
    /// Per track: whether any of its id-images showed one of the objects
    /// flagged in `watch`.
    pub saw: Vec<bool>,
    pub images: usize,
}

/// Bisects every interval between successive frames of each track's
/// `initial` list while its fitness is below `q`, down to one frame.
/// `seed` holds id-images already taken (track, frame). `view_of` maps a
/// track to the base view recorded in its tests.
#[allow(clippy::too_many_arguments)]
pub fn bisect(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    frames: &Frames,
    q: f32,
    initial: Vec<Vec<u32>>,
    mut seed: HashMap<(usize, u32), Vec<IdImage>>,
    render: &Render,
    watch: &[bool],
    view_of: impl Fn(usize) -> Option<usize>,
) -> Result<Bisected> {
    let mut lists: Vec<BTreeSet<u32>> = initial
        .iter()
        .map(|l| l.iter().copied().collect())
        .collect();
    let mut saw: Vec<bool> = (0..initial.len())
        .map(|tr| {
            seed.iter()
                .any(|(&(s, _), ims)| s == tr && ims.iter().any(|im| im.sees_any(watch)))
        })
        .collect();
    let mut pending: Vec<(usize, u32, u32)> = lists
        .iter()
        .enumerate()
        .flat_map(|(tr, l)| {
            let l: Vec<u32> = l.iter().copied().collect();
            l.windows(2).map(|w| (tr, w[0], w[1])).collect::<Vec<_>>()
        })
        .collect();
    let mut cache = std::mem::take(&mut seed);
    let mut tests = Vec::new();
    let mut images = 0;
    while !pending.is_empty() {
        let mut needed: BTreeMap<u32, BTreeSet<usize>> = BTreeMap::new();
        for &(tr, k0, k1) in &pending {
            for k in [k0, k1] {
                if !cache.contains_key(&(tr, k)) {
                    needed.entry(k).or_default().insert(tr);
                }
            }
        }
        for (k, tracks) in needed {
            let t = frames.time(k);
            engine
                .set_transforms(&scene.at(t))
                .with_context(|| format!("posing the scene at t = {t}"))?;
            for tr in tracks {
                let ims = render(&*engine, tr, t)?;
                images += ims.len();
                saw[tr] |= ims.iter().any(|im| im.sees_any(watch));
                cache.insert((tr, k), ims);
            }
        }
        let mut next = Vec::new();
        for (tr, k0, k1) in pending {
            let (a, b) = (&cache[&(tr, k0)], &cache[&(tr, k1)]);
            let f = a
                .iter()
                .zip(b)
                .map(|(a, b)| fitness(&[a, b]))
                .fold(1.0f32, f32::min);
            let split = f < q && k1 - k0 > 1;
            tests.push(IntervalTest {
                view: view_of(tr),
                t0: frames.time(k0),
                t1: frames.time(k1),
                fitness: f,
                split,
            });
            if split {
                let m = k0 + (k1 - k0) / 2;
                lists[tr].insert(m);
                next.push((tr, k0, m));
                next.push((tr, m, k1));
            }
        }
        let keep: BTreeSet<(usize, u32)> = next
            .iter()
            .flat_map(|&(tr, k0, k1)| [(tr, k0), (tr, k1)])
            .collect();
        cache.retain(|key, _| keep.contains(key));
        pending = next;
    }
    Ok(Bisected {
        frames: lists.into_iter().map(|l| l.into_iter().collect()).collect(),
        tests,
        saw,
        images,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn anim(start: f32, end: f32, fps: f32) -> Animation {
        Animation { start, end, fps }
    }

    #[test]
    fn frames_end_at_the_animation_end() {
        let f = Frames::new(anim(0.0, 1.0, 30.0));
        assert_eq!(f.last, 30);
        assert_eq!(f.time(0), 0.0);
        assert_eq!(f.time(15), 0.5);
        assert_eq!(f.time(30), 1.0);
        let f = Frames::new(anim(2.0, 3.05, 10.0));
        assert_eq!(f.last, 11);
        assert_eq!(f.time(10), 3.0);
        assert_eq!(f.time(11), 3.05);
        assert_eq!(Frames::new(anim(1.0, 1.0, 24.0)).last, 0);
    }
}
