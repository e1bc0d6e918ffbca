//! A walk's frames measured against path-traced references (`rangewalk
//! walk --check-every`): every n-th frame and the last are path-traced
//! beside the synthesis, their error goes in the walk's summary and both
//! are shown, synthesized above reference, in `contact.png`.

use std::path::Path;

use anyhow::{ensure, Context, Result};
use glam::Vec3;

use super::metrics;
use super::reference::path_trace_image;
use super::summary::write_sheet;
use crate::camera::Camera;
use crate::image::{self, RangeImage};
use crate::synth::walk::{FrameCheck, FrameChecker};
use crate::synth::Synthesizer;

/// Checks every `every`-th frame from the first, and the last, against a
/// path-traced reference of `spp` samples per pixel.
pub struct ReferenceChecks {
    every: usize,
    spp: u32,
    seed: u64,
    size: (u32, u32),
    /// Each checked frame's radiance and its reference's, for the sheet.
    sheet: Vec<(Vec<Vec3>, Vec<Vec3>)>,
}

impl ReferenceChecks {
    pub fn new(every: usize, spp: u32, seed: u64) -> Result<Self> {
        ensure!(
            every > 0,
            "--check-every 0: give a frame interval of at least 1"
        );
        ensure!(spp > 0, "--check-spp must be at least 1");
        Ok(Self {
            every,
            spp,
            seed,
            size: (0, 0),
            sheet: Vec::new(),
        })
    }
}

impl FrameChecker for ReferenceChecks {
    fn wants(&self, i: usize, n: usize) -> bool {
        i.is_multiple_of(self.every) || i + 1 == n
    }

    fn check(
        &mut self,
        synth: &mut Synthesizer,
        i: usize,
        t: f32,
        camera: &Camera,
        frame: &RangeImage,
        dir: &Path,
    ) -> Result<FrameCheck> {
        let scene = synth.scene;
        let engine = synth.engine_at(t)?;
        let (reference, seconds) = path_trace_image(scene, engine, camera, t, self.spp, self.seed)
            .with_context(|| format!("the reference of frame {i} (t = {t})"))?;
        image::write_exr(dir.join(format!("reference-{i:04}.exr")), &reference)?;
        let e = metrics::compare(frame, &reference, None)
            .with_context(|| format!("frame {i} against its reference"))?;
        self.size = (frame.width, frame.height);
        self.sheet
            .push((frame.radiance.clone(), reference.radiance));
        Ok(FrameCheck {
            frame: i,
            time: t,
            lrms: e.lrms,
            bias: e.bias,
            reference_spp: self.spp,
            reference_seconds: seconds,
        })
    }

    fn finish(&mut self, dir: &Path, exposure: f32) -> Result<()> {
        if self.sheet.is_empty() {
            return Ok(());
        }
        let rows: Vec<Vec<&[Vec3]>> = vec![
            self.sheet.iter().map(|(s, _)| s.as_slice()).collect(),
            self.sheet.iter().map(|(_, r)| r.as_slice()).collect(),
        ];
        write_sheet(dir.join("contact.png"), self.size, &rows, exposure)
    }
}
