//! `rangewalk experiment motion`: interpolation of object motion from base
//! images in time, seen from one fixed view (the paper's Table 4, §5.2.2).
//!
//! For each quality the view's time list is planned (id-images from the
//! lights and from the view), one base image is baked at the camera for
//! each time, and every frame of the animation is synthesized from them by
//! each time interpolation: linear per pixel (the paper's), motion
//! compensated, and motion compensated with direct light shaded again.
//! Each frame is compared with a path-traced reference.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Result;

use crate::eval::experiments::common::plot::{self, Plot, Scale, Series};
use crate::eval::experiments::common::sequence::{
    differences, modes_list, notes_md, write_sequence, Sequence, SequenceQuality,
};
use crate::eval::experiments::common::setup::{engine, CommonArgs, SequenceArgs, Shot};
use crate::eval::experiments::common::staging::Staging;
use crate::eval::experiments::common::synthesize::mean_flip;
use crate::eval::experiments::common::table::cell;
use crate::eval::experiments::common::table::{sig, Table};
use crate::eval::reference::Reference;
use crate::plan::Plan;
use crate::synth::{Options, TimeInterp};

/// The paper's Table 4: per quality the number of solutions, the time list
/// (frames), synthesis time (s) and frame 10's relative LRMS, all by linear
/// interpolation; the fully rendered sequence took 15,204 s.
const PAPER: [(f32, usize, &str, f64, f64); 3] = [
    (0.3, 2, "0, 48", 2711.0, 0.849),
    (0.6, 3, "0, 24, 48", 3837.0, 0.748),
    (0.9, 5, "0, 12, 24, 36, 48", 6030.0, 0.576),
];
const PAPER_FULLY_RENDERED_S: f64 = 15204.0;
/// The frame the paper reports.
pub const PAPER_FRAME: usize = 10;

/// What `rangewalk experiment motion` takes.
#[derive(Clone, Debug)]
pub struct MotionArgs {
    pub common: CommonArgs,
    /// The fixed view: a named camera of the scene. Its position is the one
    /// base view.
    pub camera: String,
    pub sequence: SequenceArgs,
}

/// The experiment's measurements.
#[derive(Clone, Debug)]
pub struct MotionResults {
    pub args: MotionArgs,
    pub times: Vec<f32>,
    /// The scene's frame rate (time lists are given in its frames).
    pub fps: f32,
    pub preview_frame: usize,
    pub base_size: u32,
    pub references: Vec<Reference>,
    pub qualities: Vec<SequenceQuality>,
    pub notes: Vec<String>,
    pub out: PathBuf,
}

/// Runs the experiment and writes its report to `args.common.out`.
pub fn run(args: &MotionArgs) -> Result<MotionResults> {
    let c = &args.common;
    let setup = c.setup()?;
    let mut scene = setup.scene.clone();
    let mut notes = setup.notes.clone();
    let a = scene.animation;
    let times = args.sequence.times((a.start, a.end), a.fps)?;
    // The plan puts its one base view at the first camera when the scene
    // has no view space: make that the fixed view.
    scene.camera(&args.camera)?;
    let k = scene
        .cameras
        .iter()
        .position(|cam| cam.name == args.camera)
        .expect("the camera was found");
    scene.cameras.swap(0, k);
    if scene.view_space.take().is_some() {
        notes.push(format!(
            "the scene's view space is set aside: one base view at camera `{}`",
            args.camera
        ));
    }
    if scene.is_static() {
        notes.push("static scene: one time, nothing to interpolate".to_string());
    }
    let (w, h) = c.size;
    let camera = scene.cameras[0].perspective(w, h)?;
    let preview_frame = if times.len() > PAPER_FRAME {
        PAPER_FRAME
    } else {
        times.len() / 2
    };
    let shots: Vec<Shot> = times
        .iter()
        .map(|&time| Shot {
            camera,
            time,
            name: args.camera.clone(),
        })
        .collect();
    let staging = Staging::begin(&c.out)?;
    let mut engine = engine(&scene, c.backend)?;
    let seq = Sequence {
        setup: &setup,
        common: c,
        scene: &scene,
        shots: &shots,
        preview_frame,
        modes: &args.sequence.time_interp,
        options: Options {
            fill: args.sequence.fill,
            bases: 1,
            supersample: args.common.supersample,
            blend: args.common.blend,
            ..Options::default()
        },
    };
    let measured = seq.measure(engine.as_mut(), staging.dir(), Plan::clone, &mut notes)?;
    let mut results = MotionResults {
        args: args.clone(),
        times,
        fps: a.fps,
        preview_frame,
        base_size: setup.base_size,
        references: measured.references,
        qualities: measured.qualities,
        notes,
        out: c.out.clone(),
    };
    write(staging.dir(), &results)?;
    results.out = staging.finish()?;
    Ok(results)
}

fn paper(q: f32) -> Option<&'static (f32, usize, &'static str, f64, f64)> {
    crate::eval::experiments::common::table::for_quality(&PAPER, q, |p| p.0)
}

/// Writes table.md, qualities.csv, frames.csv, plots and strips.
pub fn write(dir: &Path, r: &MotionResults) -> Result<()> {
    error_vs_time_plot(dir, r)?;
    write_sequence(
        dir,
        &markdown(r)?,
        &qualities_csv(r)?,
        r.args.common.size,
        &r.references[r.preview_frame].radiance,
        &r.qualities,
    )
}

/// The time list of the one view, in seconds and in frames of the scene's
/// rate.
fn time_list(q: &SequenceQuality, fps: f32) -> (String, String) {
    let times = q.plan.views.first().map_or(&[][..], |v| v.times.as_slice());
    let f: Vec<String> = times
        .iter()
        .map(|t| format!("{}", (t * fps).round()))
        .collect();
    (super::common::table::times_list(times), f.join(", "))
}

fn markdown(r: &MotionResults) -> Result<String> {
    let c = &r.args.common;
    let fps = r.fps;
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# Motion interpolation: {} (paper Table 4)\n",
        c.scene.display()
    );
    let _ = writeln!(
        md,
        "Fixed camera `{}`, {} frames over t = {} to {} s (the scene runs at {} frames/s); fill {}; \
         the one base view at the camera.\n",
        r.args.camera,
        r.times.len(),
        r.times[0],
        r.times[r.times.len() - 1],
        fps,
        <&str>::from(r.args.sequence.fill)
    );
    md.push_str(&differences(
        c,
        r.base_size,
        "time interpolation: linear per pixel between the two base times bracketing the frame \
         (the paper's `pcomb`), motion compensated (each sample moved by its object's rigid motion), \
         and re-shaded (motion compensated, diffuse direct light traced again at the frame's time)",
    ));
    md.push_str(&notes_md(&r.notes));

    md.push_str("## Scene decomposition\n\n");
    let mut t = Table::new([
        "quality",
        "base images",
        "time list (s)",
        "time list (frames)",
        "planning (s)",
        "paper base images",
        "paper time list (frames)",
    ]);
    for q in &r.qualities {
        let (s, f) = time_list(q, fps);
        let p = paper(q.quality);
        t.push([
            q.quality.to_string(),
            q.baked_images.to_string(),
            s,
            f,
            sig(q.plan_s, 3),
            p.map_or("—".into(), |p| p.1.to_string()),
            p.map_or("—".into(), |p| p.2.to_string()),
        ])?;
    }
    md.push_str(&t.to_markdown());

    md.push_str("\n## Base images\n\n");
    let mut t = Table::new([
        "quality",
        "images",
        "radiosity (s)",
        "per image (s)",
        "bake in all (s)",
    ]);
    for q in &r.qualities {
        let timing = q.bake.timing.as_ref();
        t.push([
            q.quality.to_string(),
            q.baked_images.to_string(),
            cell(timing.and_then(|t| t.radiosity_s), 3),
            cell(timing.and_then(|t| t.per_image_s()), 3),
            cell(q.bake_s(), 3),
        ])?;
    }
    md.push_str(&t.to_markdown());
    md.push_str("\nBake in all: planning, radiosity and the images.\n");

    let f = PAPER_FRAME;
    let has_frame = r.times.len() > f;
    md.push_str("\n## Synthesis and analysis\n\n");
    let mut t = Table::new([
        "method",
        "bake (s)",
        "synthesis, all frames (s)",
        "loading (s)",
        "total (s)",
        &format!("LRMS frame {f}"),
        "mean LRMS",
        "max LRMS",
        "mean bias",
        "mean LRMS, emitters excluded",
        "mean block LRMS",
        "mean block p99",
        "mean FLIP",
        "paper time (s)",
        &format!("paper LRMS frame {f}"),
    ]);
    let ref_s: Option<f64> = r.references.iter().map(|x| x.seconds).sum();
    t.push([
        format!("fully rendered: path tracer at {} spp", c.reference_spp),
        "—".into(),
        cell(ref_s, 3),
        "—".into(),
        cell(ref_s, 3),
        "0".into(),
        "0".into(),
        "0".into(),
        "0".into(),
        "0".into(),
        "0".into(),
        "0".into(),
        "0".into(),
        sig(PAPER_FULLY_RENDERED_S, 5),
        "0.000".into(),
    ])?;
    for q in &r.qualities {
        for m in &q.modes {
            let p = paper(q.quality).filter(|_| m.mode == TimeInterp::Linear);
            let bake = q.bake_s();
            t.push([
                format!("q = {}, {}", q.quality, <&str>::from(m.mode)),
                cell(bake, 3),
                sig(m.synth_s(), 3),
                sig(m.load_s(), 3),
                cell(bake.map(|b| b + m.synth_s() + m.load_s()), 3),
                if has_frame {
                    sig(m.frames[f].error.lrms, 3)
                } else {
                    "—".into()
                },
                sig(m.mean_lrms(), 3),
                sig(m.max_lrms(), 3),
                format!("{:+.4}", m.mean_bias()),
                cell(m.mean_lrms_without_emitters(), 3),
                sig(m.mean_block_lrms(), 3),
                sig(m.mean_block_p99(), 3),
                cell(mean_flip(&m.frames), 3),
                p.map_or("—".into(), |p| sig(p.3, 4)),
                p.map_or("—".into(), |p| format!("{:.3}", p.4)),
            ])?;
        }
    }
    md.push_str(&t.to_markdown());
    let _ = writeln!(
        md,
        "\nThe paper's figures are for linear interpolation against Radiance HQ; its time is \
         base-image construction and reconstruction of the sequence. Synthesis excludes reading \
         bases, which is under loading. `strip-q<q>.png`: frame {} (t = {} s), the reference then {}.",
        r.preview_frame,
        r.times[r.preview_frame],
        modes_list(&r.args.sequence.time_interp)
    );
    Ok(md)
}

fn qualities_csv(r: &MotionResults) -> Result<Table> {
    let mut t = Table::new([
        "quality",
        "mode",
        "base_images",
        "time_list",
        "planning_s",
        "radiosity_s",
        "render_s",
        "bake_s",
        "synth_s",
        "load_s",
        "mean_lrms",
        "max_lrms",
        "mean_bias",
        "mean_lrms_without_emitters",
        "mean_block_lrms",
        "mean_block_p99",
        "mean_flip",
    ]);
    for q in &r.qualities {
        let timing = q.bake.timing.as_ref();
        let opt = |x: Option<f64>| x.map_or(String::new(), |x| x.to_string());
        for m in &q.modes {
            t.push([
                q.quality.to_string(),
                <&str>::from(m.mode).to_string(),
                q.baked_images.to_string(),
                q.plan.views.first().map_or(String::new(), |v| {
                    v.times
                        .iter()
                        .map(|t| t.to_string())
                        .collect::<Vec<_>>()
                        .join(";")
                }),
                q.plan_s.to_string(),
                opt(timing.and_then(|t| t.radiosity_s)),
                opt(timing.map(|t| t.render_s)),
                opt(q.bake_s()),
                m.synth_s().to_string(),
                m.load_s().to_string(),
                m.mean_lrms().to_string(),
                m.max_lrms().to_string(),
                m.mean_bias().to_string(),
                opt(m.mean_lrms_without_emitters()),
                m.mean_block_lrms().to_string(),
                m.mean_block_p99().to_string(),
                opt(mean_flip(&m.frames)),
            ])?;
        }
    }
    Ok(t)
}

/// Mean LRMS against the whole sequence's time (bake and synthesis), one
/// line per mode through the qualities, and the fully rendered sequence.
fn error_vs_time_plot(dir: &Path, r: &MotionResults) -> Result<()> {
    let mut series: Vec<Series> = r
        .args
        .sequence
        .time_interp
        .iter()
        .map(|&mode| Series {
            label: <&str>::from(mode).to_string(),
            points: r
                .qualities
                .iter()
                .filter_map(|q| {
                    let m = q.modes.iter().find(|m| m.mode == mode)?;
                    Some((q.bake_s()? + m.synth_s() + m.load_s(), m.mean_lrms()))
                })
                .collect(),
        })
        .collect();
    if let Some(s) = r.references.iter().map(|x| x.seconds).sum::<Option<f64>>() {
        series.push(Series {
            label: format!(
                "fully rendered ({} spp), error 0",
                r.args.common.reference_spp
            ),
            points: vec![(s, 0.0)],
        });
    }
    plot::write_png(
        dir.join("error_vs_time.png"),
        &Plot {
            title: "Motion interpolation: error against time",
            x_label: "seconds for the sequence (bake and synthesis)",
            y_label: "mean LRMS",
            scale: Scale::Linear,
            series: &series,
        },
    )
}
