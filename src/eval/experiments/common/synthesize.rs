//! Frames synthesized from a bake and compared with their references:
//! LRMS and FLIP over the pixels that show no light source.

use anyhow::{Context, Result};
use glam::Vec3;

use super::setup::Shot;
use super::table::mean;
use crate::accel::InstancedEngine;
use crate::bake::Bake;
use crate::camera::Camera;
use crate::eval::flip::Flip;
use crate::eval::metrics::{self, ImageError, Pixels};
use crate::image::NO_HIT;
use crate::scene::Scene;
use crate::synth::{self, Options, Synthesizer};

/// One synthesized frame compared with its reference.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthFrame {
    pub frame: usize,
    /// Scene time (s).
    pub time: f32,
    /// Synthesis wall time, base loading excluded.
    pub synth_s: f64,
    /// Reading and preparing base images for this frame.
    pub load_s: f64,
    /// Base images the frame was made from.
    pub images: usize,
    /// Pixels nothing reached.
    pub holes: usize,
    /// Pixels background fill filled.
    pub filled: usize,
    pub error: ImageError,
    /// The error over the pixels that show no light source (see
    /// [`emitter_free`]); `None` where none is in view.
    pub without_emitters: Option<ImageError>,
    pub flip: Option<f64>,
}

impl SynthFrame {
    /// What the frame cost in all.
    pub fn seconds(&self) -> f64 {
        self.synth_s + self.load_s
    }
}

/// Frames synthesized by one method, and their radiance.
pub struct SynthRun {
    pub frames: Vec<SynthFrame>,
    pub images: Vec<Vec<Vec3>>,
}

/// What a synthesized frame is compared with: the reference's radiance and
/// the pixels that show no light source.
#[derive(Clone, Copy, Debug)]
pub struct Truth<'a> {
    pub radiance: &'a [Vec3],
    /// The reference's width and height.
    pub size: (u32, u32),
    pub emitter_free: Option<&'a [bool]>,
}

impl Truth<'_> {
    /// `test`'s error over every pixel, and over those without emitters.
    pub fn compare<'t>(
        &self,
        test: impl Into<Pixels<'t>>,
    ) -> Result<(ImageError, Option<ImageError>)> {
        let test = test.into();
        let reference = Pixels::new(self.size.0, self.size.1, self.radiance);
        let all = metrics::compare(test, reference, None)?;
        let without = self
            .emitter_free
            .map(|m| metrics::compare(test, reference, Some(m)))
            .transpose()?;
        Ok((all, without))
    }
}

/// The pixels of `camera`'s view at `t` that neither show a light source
/// through their centre nor border one that does (so that an edge pixel
/// partly covering a light counts as showing it); `None` when no light
/// source is in view. A small bright light's edge, resampled a fraction of
/// a pixel off, outweighs everything else in LRMS; without those pixels
/// LRMS measures the lighting.
pub fn emitter_free(
    scene: &Scene,
    engine: &mut dyn InstancedEngine,
    camera: &Camera,
    t: f32,
) -> Result<Option<Vec<bool>>> {
    engine.set_transforms(&scene.at(t))?;
    let ids = crate::plan::idimage::render(&*engine, &crate::plan::IdView::Camera(*camera));
    let emits: Vec<bool> = ids
        .ids
        .iter()
        .map(|&o| o != NO_HIT && scene.material_of(o).emission.is_some())
        .collect();
    Ok(emits
        .contains(&true)
        .then(|| away_from(&emits, ids.width as usize)))
}

/// The pixels that are not marked and have no marked neighbour (of
/// eight), of a row-major image `w` pixels wide.
fn away_from(marked: &[bool], w: usize) -> Vec<bool> {
    let h = marked.len() / w;
    let mut out = vec![true; marked.len()];
    for (k, _) in marked.iter().enumerate().filter(|(_, &m)| m) {
        let (x, y) = (k % w, k / w);
        for j in y.saturating_sub(1)..=(y + 1).min(h - 1) {
            for i in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                out[j * w + i] = false;
            }
        }
    }
    out
}

/// Synthesizes every shot from `bake` with `opts` (a fresh synthesizer, so
/// that its loading of bases is counted here) and compares each frame with
/// its reference; FLIP in one batch at the end.
pub fn synthesize(
    scene: &Scene,
    bake: &Bake,
    shots: &[Shot],
    truths: &[Truth],
    opts: &Options,
    flip: Option<&Flip>,
    tag: &str,
) -> Result<SynthRun> {
    let mut synth = Synthesizer::new(scene, bake, synth::DEFAULT_BUDGET);
    let mut frames = Vec::with_capacity(shots.len());
    let mut images = Vec::with_capacity(shots.len());
    for (i, (shot, truth)) in shots.iter().zip(truths).enumerate() {
        let (img, stats) = synth
            .frame(&shot.camera, shot.time, opts)
            .with_context(|| format!("{tag}: frame {i} (t = {} s)", shot.time))?;
        let (error, without_emitters) = truth
            .compare(&img)
            .with_context(|| format!("{tag}: frame {i} (t = {} s)", shot.time))?;
        let synth_s = stats.seconds - stats.load_seconds;
        eprintln!(
            "{tag}: frame {}/{} t = {:.4} s: LRMS {:.4}, {} hole(s) ({:.1} ms + {:.3} s loading)",
            i + 1,
            shots.len(),
            shot.time,
            error.lrms,
            stats.holes,
            1e3 * synth_s,
            stats.load_seconds
        );
        frames.push(SynthFrame {
            frame: i,
            time: shot.time,
            synth_s,
            load_s: stats.load_seconds,
            images: stats.images.len(),
            holes: stats.holes,
            filled: stats.filled,
            error,
            without_emitters,
            flip: None,
        });
        images.push(img.radiance);
    }
    if let Some(first) = shots.first() {
        let refs: Vec<&[Vec3]> = truths.iter().map(|t| t.radiance).collect();
        for (f, v) in frames
            .iter_mut()
            .zip(flip_means(flip, &first.camera, &refs, &images)?)
        {
            f.flip = v;
        }
    }
    Ok(SynthRun { frames, images })
}

/// Mean FLIP of frames, `None` when any frame has none.
pub fn mean_flip(frames: &[SynthFrame]) -> Option<f64> {
    frames
        .iter()
        .map(|f| f.flip)
        .collect::<Option<Vec<f64>>>()
        .map(|v| mean(v.into_iter()))
}

/// FLIP of each image against its reference (all of `camera`'s size), in
/// one batch; `None` for each when FLIP is left out.
pub(crate) fn flip_means(
    flip: Option<&Flip>,
    camera: &Camera,
    refs: &[&[Vec3]],
    images: &[Vec<Vec3>],
) -> Result<Vec<Option<f64>>> {
    let Some(f) = flip else {
        return Ok(vec![None; images.len()]);
    };
    let pairs: Vec<(&[Vec3], &[Vec3])> = refs
        .iter()
        .zip(images)
        .map(|(r, t)| (*r, t.as_slice()))
        .collect();
    Ok(f.hdr_means(camera.width, camera.height, &pairs)?
        .into_iter()
        .map(Some)
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_at_and_beside_a_light_are_left_out() {
        // 4 x 3, a light at (1, 1): everything within one pixel of it goes.
        let mut marked = vec![false; 12];
        marked[5] = true;
        let keep = away_from(&marked, 4);
        let expect = [
            false, false, false, true, //
            false, false, false, true, //
            false, false, false, true,
        ];
        assert_eq!(keep, expect);
        // A light in the corner reaches no further than its neighbours.
        let mut marked = vec![false; 12];
        marked[11] = true;
        let gone: Vec<usize> = (0..12).filter(|&k| !away_from(&marked, 4)[k]).collect();
        assert_eq!(gone, [6, 7, 10, 11]);
    }
}
