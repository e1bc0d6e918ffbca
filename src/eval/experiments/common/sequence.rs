//! The experiments over a sequence of frames (`motion`, `walkthrough`):
//! each time interpolation's frames, their errors and costs, and the
//! report text every synthesis experiment shares.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use glam::Vec3;

use super::convergence::Measure;
use super::plot::{self, Series};
use super::setup::{
    bake_cached, plan_timed, quality_dir, references_of, BakeCost, CommonArgs, Setup, Shot,
};
use super::staging::{BAKES_DIR, REFERENCE_DIR};
use super::synthesize::{emitter_free, mean_flip, synthesize, SynthFrame, Truth};
use super::table::{mean, Table};
use crate::accel::InstancedEngine;
use crate::bake::{self};
use crate::eval::reference::{self, Reference};
use crate::eval::sheet::{exposure_for, write_strip};
use crate::plan::Plan;
use crate::quality::Quality;
use crate::scene::Scene;
use crate::synth::{Blend, Options, TimeInterp};

/// A sequence of frames synthesized with one time interpolation.
#[derive(Clone, Debug)]
pub struct ModeRun {
    pub mode: TimeInterp,
    pub frames: Vec<SynthFrame>,
    /// Radiance of the preview frame.
    pub preview: Vec<Vec3>,
}

impl ModeRun {
    pub fn synth_s(&self) -> f64 {
        self.frames.iter().map(|f| f.synth_s).sum()
    }

    pub fn load_s(&self) -> f64 {
        self.frames.iter().map(|f| f.load_s).sum()
    }

    /// Mean cost of a frame, loading included.
    pub fn per_frame_s(&self) -> f64 {
        mean(self.frames.iter().map(SynthFrame::seconds))
    }

    /// Mean synthesis time of a frame, loading excluded.
    pub fn synth_per_frame_s(&self) -> f64 {
        mean(self.frames.iter().map(|f| f.synth_s))
    }

    pub fn mean_lrms(&self) -> f64 {
        mean(self.frames.iter().map(|f| f.error.lrms))
    }

    pub fn max_lrms(&self) -> f64 {
        self.frames
            .iter()
            .map(|f| f.error.lrms)
            .fold(f64::NAN, f64::max)
    }

    pub fn mean_bias(&self) -> f64 {
        mean(self.frames.iter().map(|f| f.error.bias))
    }

    pub fn mean_block_lrms(&self) -> f64 {
        mean(self.frames.iter().map(|f| f.error.block_lrms))
    }

    pub fn mean_block_p99(&self) -> f64 {
        mean(self.frames.iter().map(|f| f.error.block_p99))
    }

    /// Mean LRMS without the pixels that show light sources, over the
    /// frames that show one; `None` when none does.
    pub fn mean_lrms_without_emitters(&self) -> Option<f64> {
        let v: Vec<f64> = self
            .frames
            .iter()
            .filter_map(|f| f.without_emitters.map(|e| e.lrms))
            .collect();
        (!v.is_empty()).then(|| mean(v.into_iter()))
    }
}

/// One quality of a frame sequence (`motion`, `walkthrough`): its plan,
/// bake and frames by each time interpolation.
#[derive(Clone, Debug)]
pub struct SequenceQuality {
    pub quality: f32,
    /// The plan of the view space (or the one view).
    pub plan: Plan,
    pub plan_s: f64,
    /// Views and images baked: all of the plan's, or those the frames use.
    pub baked_views: usize,
    pub baked_images: usize,
    pub bake: BakeCost,
    pub modes: Vec<ModeRun>,
}

impl SequenceQuality {
    /// Images of the whole plan.
    pub fn planned_images(&self) -> usize {
        self.plan.views.iter().map(|v| v.times.len()).sum()
    }

    /// Planning, radiosity and the images baked, as measured.
    pub fn bake_s(&self) -> Option<f64> {
        let t = self.bake.timing.as_ref()?;
        Some(self.plan_s + t.total_s()?)
    }

    /// Planning, radiosity and every image of the plan, those not baked
    /// counted at the mean cost of those that were: the framework's whole
    /// bake.
    pub fn full_bake_s(&self) -> Option<f64> {
        let t = self.bake.timing.as_ref()?;
        Some(self.plan_s + t.radiosity_s? + t.per_image_s()? * self.planned_images() as f64)
    }
}

/// The frames of a sequence experiment (`motion`, `walkthrough`) and how
/// to make them.
pub struct Sequence<'a> {
    pub setup: &'a Setup,
    pub common: &'a CommonArgs,
    /// The scene as planned (it may differ from `setup.scene` in its view
    /// space or camera order, never in what the bakes hash).
    pub scene: &'a Scene,
    pub shots: &'a [Shot],
    pub preview_frame: usize,
    pub modes: &'a [TimeInterp],
    /// Fill and bases; the time interpolation is each of `modes`.
    pub options: Options,
}

/// What a sequence experiment measured.
pub struct Measured {
    pub references: Vec<Reference>,
    pub qualities: Vec<SequenceQuality>,
}

impl Sequence<'_> {
    /// The references of every shot (cached in `out/reference`), then for
    /// each quality: the plan, a bake of what `choose` keeps of it (in
    /// `out/bakes/q<q>`, reused when there) and every frame by each mode.
    /// What was reused is added to `notes`.
    pub fn measure(
        &self,
        engine: &mut dyn InstancedEngine,
        out: &Path,
        choose: impl Fn(&Plan) -> Plan,
        notes: &mut Vec<String>,
    ) -> Result<Measured> {
        let references = references_of(
            self.scene,
            engine,
            self.shots,
            self.common.reference_spp,
            &out.join(REFERENCE_DIR),
        )?;
        notes.extend(reference::reuse_note(&references));
        let masks = self
            .shots
            .iter()
            .map(|s| emitter_free(self.scene, engine, &s.camera, s.time))
            .collect::<Result<Vec<_>>>()?;
        let truths: Vec<Truth> = references
            .iter()
            .zip(&masks)
            .zip(self.shots)
            .map(|((r, m), shot)| Truth {
                radiance: &r.radiance,
                size: (shot.camera.width, shot.camera.height),
                emitter_free: m.as_deref(),
            })
            .collect();
        let mut qualities = Vec::new();
        for &q in &self.setup.qualities {
            let dir = out.join(BAKES_DIR).join(quality_dir("", q));
            let settings = self.common.bake_settings(q, self.setup.base_size);
            qualities.push(
                self.quality(engine, q, &settings, &dir, &truths, &choose)
                    .with_context(|| format!("quality {}", q.get()))?,
            );
        }
        if qualities.iter().any(|r| r.bake.reused) {
            notes.push(
                "bakes reused from an earlier run: their times are the ones that run recorded"
                    .to_string(),
            );
        }
        Ok(Measured {
            references,
            qualities,
        })
    }

    /// Plans at quality `q`, bakes what `choose` keeps of the plan into
    /// `dir` (reusing a bake there) and synthesizes every frame by each
    /// mode.
    fn quality(
        &self,
        engine: &mut dyn InstancedEngine,
        q: Quality,
        settings: &bake::Settings,
        dir: &Path,
        truths: &[Truth],
        choose: impl Fn(&Plan) -> Plan,
    ) -> Result<SequenceQuality> {
        let tag = format!("q = {}", q.get());
        engine.set_transforms(&self.scene.at(self.scene.animation.start))?;
        let (plan, plan_s) = plan_timed(self.scene, engine, q, self.common.view_fitness)?;
        let baked = choose(&plan);
        eprintln!(
            "{tag}: {} view(s), {} image(s) planned ({plan_s:.3} s); baking {} view(s)",
            plan.views.len(),
            plan.views.iter().map(|v| v.times.len()).sum::<usize>(),
            baked.views.len()
        );
        let bake = bake_cached(self.scene, dir, settings, &baked, engine)?;
        let mut modes = Vec::with_capacity(self.modes.len());
        for &mode in self.modes {
            let opts = Options {
                time_interp: mode,
                ..self.options
            };
            let mut run = synthesize(
                self.scene,
                &bake.bake,
                self.shots,
                truths,
                &opts,
                self.setup.flip.as_ref(),
                &format!("{tag} {}", <&str>::from(mode)),
            )?;
            modes.push(ModeRun {
                mode,
                frames: run.frames,
                preview: run.images.swap_remove(self.preview_frame),
            });
        }
        Ok(SequenceQuality {
            quality: q.get(),
            baked_views: baked.views.len(),
            baked_images: baked.views.iter().map(|v| v.times.len()).sum(),
            plan,
            plan_s,
            bake: bake.cost(),
            modes,
        })
    }
}

/// The modes' names, comma-separated.
pub fn modes_list(modes: &[TimeInterp]) -> String {
    modes
        .iter()
        .map(|&m| <&str>::from(m))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Writes what every sequence experiment reports: `table.md`,
/// `qualities.csv`, `frames.csv`, `error_per_frame.png` and the strips of
/// the preview frame (whose reference is `reference`).
pub fn write_sequence(
    dir: &Path,
    markdown: &str,
    qualities_csv: &Table,
    size: (u32, u32),
    reference: &[Vec3],
    qualities: &[SequenceQuality],
) -> Result<()> {
    let path = dir.join("table.md");
    std::fs::write(&path, markdown).with_context(|| format!("writing {}", path.display()))?;
    qualities_csv.write_csv(dir.join("qualities.csv"))?;
    frames_csv(qualities)?.write_csv(dir.join("frames.csv"))?;
    error_per_frame_plot(dir, qualities)?;
    strips(dir, size, reference, qualities)
}

/// One row per quality, mode and frame.
pub fn frames_csv(qualities: &[SequenceQuality]) -> Result<Table> {
    let mut t = Table::new([
        "quality",
        "mode",
        "frame",
        "time_s",
        "lrms",
        "bias",
        "lrms_without_emitters",
        "block_lrms",
        "block_p99",
        "flip",
        "synth_s",
        "load_s",
        "images",
        "holes",
        "filled",
    ]);
    for q in qualities {
        for m in &q.modes {
            for f in &m.frames {
                t.push([
                    q.quality.to_string(),
                    <&str>::from(m.mode).to_string(),
                    f.frame.to_string(),
                    f.time.to_string(),
                    f.error.lrms.to_string(),
                    f.error.bias.to_string(),
                    f.without_emitters
                        .map_or(String::new(), |e| e.lrms.to_string()),
                    f.error.block_lrms.to_string(),
                    f.error.block_p99.to_string(),
                    f.flip.map_or(String::new(), |x| x.to_string()),
                    f.synth_s.to_string(),
                    f.load_s.to_string(),
                    f.images.to_string(),
                    f.holes.to_string(),
                    f.filled.to_string(),
                ])?;
            }
        }
    }
    Ok(t)
}

/// `error_per_frame.png`: LRMS against scene time, one line per quality
/// and mode.
fn error_per_frame_plot(dir: &Path, qualities: &[SequenceQuality]) -> Result<()> {
    let series: Vec<Series> = qualities
        .iter()
        .flat_map(|q| {
            q.modes.iter().map(move |m| Series {
                label: format!("q = {}, {}", q.quality, <&str>::from(m.mode)),
                points: m
                    .frames
                    .iter()
                    .map(|f| (f.time as f64, f.error.lrms))
                    .collect(),
            })
        })
        .collect();
    plot::error_per_frame(dir, &series)
}

/// `strip-q<q>.png` per quality: the preview frame's reference, then each
/// mode's frame, at the reference's exposure.
fn strips(
    dir: &Path,
    size: (u32, u32),
    reference: &[Vec3],
    qualities: &[SequenceQuality],
) -> Result<()> {
    let exposure = exposure_for(reference);
    for q in qualities {
        let mut images = vec![reference];
        images.extend(q.modes.iter().map(|m| m.preview.as_slice()));
        write_strip(
            dir.join(format!("strip-q{}.png", q.quality)),
            size,
            &images,
            exposure,
        )?;
    }
    Ok(())
}

/// The lines of a report's header that say what differs from the paper.
pub fn differences(args: &CommonArgs, base_size: u32, what: &str) -> String {
    let mut md = String::from("What differs from the paper:\n\n");
    let _ = writeln!(
        md,
        "- references: this project's path tracer at {} spp (the paper: Radiance, high-quality settings);",
        args.reference_spp
    );
    let _ = writeln!(
        md,
        "- base images: {0}x{0} full-sphere (equal-area octahedral) range images by the multipass \
         renderer at {1} spp, indirect light from radiosity records at the same quality (the paper: \
         Radiance range images, size not stated);",
        base_size, args.base_spp
    );
    let _ = writeln!(
        md,
        "- frames {}x{} (the paper's not stated), at {2}x{2} subpixels a pixel where splats fill \
         (fill foreground and both), bases blended {3}; {what};",
        args.size.0,
        args.size.1,
        args.supersample,
        match args.blend {
            Blend::Average => "by averaging where they agree",
            Blend::Nearest => "nearest first (the paper's order)",
        }
    );
    let _ = writeln!(
        md,
        "- ray engine {}, {} threads; times are wall-clock seconds on this machine (the paper's: \
         minutes on 1996 workstations).\n",
        args.backend,
        rayon::current_num_threads()
    );
    md.push_str("Holes in synthesized frames count as black.\n\n");
    md.push_str(ERRORS_MD);
    md
}

/// What the error columns of every report mean.
pub const ERRORS_MD: &str = "Errors against the reference: LRMS = RMS(Y - Y_ref) / mean(Y_ref) on \
    Rec. 709 luminance over all pixels, bias = mean(Y) / mean(Y_ref) - 1, \
    block LRMS = the same RMS over the means of 8x8 blocks (per-pixel noise averages out, seams and \
    wrong patches stay), block p99 = the 99th percentile over blocks of |block mean - reference \
    block mean| / mean(Y_ref) (a local artifact on more than 1% of the blocks), FLIP = mean \
    HDR-FLIP (a perceptual difference in [0, 1]).\n\n";

/// A list of notes under a heading, or nothing.
pub fn notes_md(notes: &[String]) -> String {
    let mut md = String::new();
    if !notes.is_empty() {
        md.push_str("Notes:\n\n");
        for n in notes {
            let _ = writeln!(md, "- {n}");
        }
        md.push('\n');
    }
    md
}

impl Measure {
    /// The mean error of `m`'s frames, where every frame has it.
    pub fn mean(self, m: &ModeRun) -> Option<f64> {
        match self {
            Measure::Lrms => Some(m.mean_lrms()),
            Measure::Flip => mean_flip(&m.frames),
        }
    }
}
