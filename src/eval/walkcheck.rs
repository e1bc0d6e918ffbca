//! A walk's frames measured against path-traced references (`rangewalk
//! walk --check-every`): every n-th frame and the last are path-traced
//! beside the synthesis, their error goes in the walk's summary and
//! `contact.png` shows them, one column per checked frame: the synthesized
//! frame, its reference and FLIP's error map of the two.
//!
//! The error is LRMS and bias, which the paper reports, the 8×8-block LRMS
//! and its 99th percentile, and FLIP: a silhouette of a few hundred wrong
//! pixels barely moves LRMS, and a viewer sees it first.

use std::path::Path;

use anyhow::{ensure, Context, Result};
use glam::Vec3;

use super::flip::Flip;
use super::metrics;
use super::reference::path_trace_image;
use super::sheet::write_sheet_srgb8;
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
    /// `None`: FLIP left out.
    flip: Option<Flip>,
    size: (u32, u32),
    /// Each checked frame's radiance, its reference's and FLIP's error map
    /// (8-bit sRGB), for the sheet.
    sheet: Vec<Checked>,
}

struct Checked {
    frame: Vec<Vec3>,
    reference: Vec<Vec3>,
    flip_map: Option<Vec<u8>>,
}

impl ReferenceChecks {
    pub fn new(every: usize, spp: u32, seed: u64, flip: Option<Flip>) -> Result<Self> {
        ensure!(
            every > 0,
            "--check-every 0: give a frame interval of at least 1"
        );
        ensure!(spp > 0, "--check-spp must be at least 1");
        Ok(Self {
            every,
            spp,
            seed,
            flip,
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
        let flip = self
            .flip
            .as_ref()
            .map(|f| {
                let pairs = [(reference.radiance.as_slice(), frame.radiance.as_slice())];
                let mut maps = f.hdr_maps(frame.width, frame.height, &pairs)?;
                anyhow::Ok(maps.remove(0))
            })
            .transpose()
            .with_context(|| format!("FLIP of frame {i} against its reference"))?;
        self.size = (frame.width, frame.height);
        let check = FrameCheck {
            frame: i,
            time: t,
            lrms: e.lrms,
            bias: e.bias,
            block_lrms: e.block_lrms,
            block_p99: e.block_p99,
            flip: flip.as_ref().map(|m| m.mean),
            reference_spp: self.spp,
            reference_seconds: seconds,
        };
        self.sheet.push(Checked {
            frame: frame.radiance.clone(),
            reference: reference.radiance,
            flip_map: flip.map(|m| m.rgb),
        });
        Ok(check)
    }

    /// `contact.png`: synthesized frames in the top row, their references
    /// below at the same exposure, and FLIP's error maps in a third row
    /// unless FLIP was left out.
    fn finish(&mut self, dir: &Path, exposure: f32) -> Result<()> {
        if self.sheet.is_empty() {
            return Ok(());
        }
        let tonemapped = |img: &[Vec3]| image::tonemap_srgb8(img, exposure);
        let mut rows = vec![
            self.sheet.iter().map(|c| tonemapped(&c.frame)).collect(),
            self.sheet
                .iter()
                .map(|c| tonemapped(&c.reference))
                .collect(),
        ];
        let maps: Vec<Vec<u8>> = self
            .sheet
            .iter_mut()
            .filter_map(|c| c.flip_map.take())
            .collect();
        if !maps.is_empty() {
            rows.push(maps);
        }
        write_sheet_srgb8(dir.join("contact.png"), self.size, &rows)
    }
}
