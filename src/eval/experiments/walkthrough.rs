//! `rangewalk experiment walkthrough`: the whole framework on a walk
//! through an animated scene (the paper's Table 5, §5.3).
//!
//! For each quality: plan the view space (base views and their time
//! lists), simplify the scene and solve radiosity over the animation, bake
//! the base images, then synthesize every frame of a walk path by each time
//! interpolation. Every phase is timed and every frame compared with a
//! path-traced frame of the same camera and time. The path tracer's
//! convergence on one frame gives the time it would need to reach each
//! quality's error, and from that the number of frames at which the bake
//! pays for itself.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{ensure, Result};
use glam::Vec3;

use crate::eval::experiments::common::convergence::{
    break_even, convergence, convergence_series, convergence_table, equal_error_seconds,
    seconds_per_sample, speedup, ConvergencePoint, Measure, Reach, Target,
};
use crate::eval::experiments::common::plot::{self, Plot, Scale, Series};
use crate::eval::experiments::common::sequence::{
    differences, modes_list, notes_md, write_sequence, Measured, ModeRun, Sequence, SequenceQuality,
};
use crate::eval::experiments::common::setup::{engine, CommonArgs, SequenceArgs, Shot};
use crate::eval::experiments::common::staging::Staging;
use crate::eval::experiments::common::synthesize::mean_flip;
use crate::eval::experiments::common::table::cell;
use crate::eval::experiments::common::table::{sig, Table};
use crate::eval::reference::Reference;
use crate::plan::Plan;
use crate::synth::{Options, TimeInterp};

/// The paper's Table 5 (minutes): scene decomposition and base images, and
/// reconstruction of the 30-frame walk, per quality; the 30 frames fully
/// rendered took 4,113.54 minutes.
const PAPER: [(f32, f64, f64); 3] = [
    (0.3, 1213.53, 90.0),
    (0.6, 2894.22, 210.0),
    (0.9, 7746.76, 480.0),
];
const PAPER_FULLY_RENDERED_MIN: f64 = 4113.54;
const PAPER_FRAMES: usize = 30;

/// Which planned views are baked.
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    strum::Display,
    strum::EnumString,
    strum::IntoStaticStr,
    strum::VariantArray,
    strum::EnumMessage,
)]
#[strum(serialize_all = "lowercase")]
pub enum BakeViews {
    /// Every view of the plan: the framework's bake, for any path.
    All,
    /// Only the views the walk's frames take as their nearest: a cheaper
    /// run of the same frames; the whole bake is then estimated from the
    /// measured cost per image.
    Used,
}

/// What `rangewalk experiment walkthrough` takes.
#[derive(Clone, Debug)]
pub struct WalkthroughArgs {
    pub common: CommonArgs,
    /// Walk path of the scene.
    pub path: String,
    pub sequence: SequenceArgs,
    /// Base views each frame is made from, nearest first.
    pub bases: usize,
    /// Which planned views to bake.
    pub bake_views: BakeViews,
    /// Length of the walk-through (frames) the bake is amortized over in
    /// the summary's speed-up.
    pub amortize_frames: u64,
}

/// The experiment's measurements.
#[derive(Clone, Debug)]
pub struct WalkResults {
    pub args: WalkthroughArgs,
    pub times: Vec<f32>,
    pub preview_frame: usize,
    pub base_size: u32,
    pub references: Vec<Reference>,
    /// The path tracer on the preview frame at 1, 2, 4, ... spp.
    pub convergence: Vec<ConvergencePoint>,
    pub qualities: Vec<SequenceQuality>,
    pub notes: Vec<String>,
    pub out: PathBuf,
}

/// Runs the experiment and writes its report to `args.common.out`.
pub fn run(args: &WalkthroughArgs) -> Result<WalkResults> {
    let c = &args.common;
    ensure!(args.bases > 0, "--bases must be at least 1");
    ensure!(
        args.amortize_frames > 0,
        "--amortize-frames must be at least 1"
    );
    let setup = c.setup()?;
    let scene = &setup.scene;
    let mut notes = setup.notes.clone();
    let path = scene.path(&args.path)?.clone();
    let times = args.sequence.times(path.span(), scene.animation.fps)?;
    ensure!(
        scene.view_space.is_some(),
        "{} has no view space to plan base views in",
        scene.source.display()
    );
    let (w, h) = c.size;
    let shots = times
        .iter()
        .map(|&t| {
            Ok(Shot {
                camera: path.at(t).perspective(w, h)?,
                time: t,
                name: format!("path-{}", path.name),
            })
        })
        .collect::<Result<Vec<Shot>>>()?;
    for s in &shots {
        if let Some(warning) = crate::synth::view_space_warning(
            scene,
            &format!("path `{}` at t = {}", path.name, s.time),
            s.camera.position,
        ) {
            notes.push(warning.trim_start_matches("warning: ").to_string());
        }
    }
    if args.bake_views == BakeViews::Used {
        notes.push(format!(
            "only the base views the frames take as their {} nearest are baked (--bake-views used); \
             the bake of the whole plan is estimated from the measured cost per image, and break-even \
             and speed-up use that estimate",
            args.bases
        ));
    }
    let preview_frame = times.len() / 2;
    let staging = Staging::begin(&c.out)?;
    let mut engine = engine(scene, c.backend)?;
    let seq = Sequence {
        setup: &setup,
        common: c,
        scene,
        shots: &shots,
        preview_frame,
        modes: &args.sequence.time_interp,
        options: Options {
            fill: args.sequence.fill,
            bases: args.bases,
            supersample: args.common.supersample,
            blend: args.common.blend,
            ..Options::default()
        },
    };
    let positions: Vec<Vec3> = shots.iter().map(|s| s.camera.position).collect();
    let choose = |plan: &Plan| match args.bake_views {
        BakeViews::All => plan.clone(),
        BakeViews::Used => used_views(plan, &positions, args.bases),
    };
    let Measured {
        references,
        qualities: runs,
    } = seq.measure(engine.as_mut(), staging.dir(), choose, &mut notes)?;

    // The path tracer's convergence on the preview frame, far enough to
    // pass the best mean error of any quality and mode.
    let all_modes = || runs.iter().flat_map(|q| q.modes.iter());
    let target = Target {
        max_spp: (c.reference_spp / 4).max(1),
        seconds: all_modes().map(ModeRun::per_frame_s).fold(0.0, f64::max),
        lrms: all_modes()
            .map(ModeRun::mean_lrms)
            .fold(f64::INFINITY, f64::min),
        flip: all_modes()
            .filter_map(|m| Measure::Flip.mean(m))
            .reduce(f64::min),
    };
    let shot = &shots[preview_frame];
    let convergence = convergence(
        scene,
        engine.as_mut(),
        &shot.camera,
        shot.time,
        &references[preview_frame].radiance,
        target,
        setup.flip.as_ref(),
    )?;

    let mut results = WalkResults {
        args: args.clone(),
        times,
        preview_frame,
        base_size: setup.base_size,
        references,
        convergence,
        qualities: runs,
        notes,
        out: c.out.clone(),
    };
    write(staging.dir(), &results)?;
    results.out = staging.finish()?;
    Ok(results)
}

/// The plan cut down to the views that cameras at `positions` take as
/// their `bases` nearest (nearest first, the lower index first among
/// equals, as the synthesis chooses). The views keep their order, so the
/// synthesis picks the same views from the cut plan as from the whole.
pub fn used_views(plan: &Plan, positions: &[Vec3], bases: usize) -> Plan {
    let mut used = vec![false; plan.views.len()];
    for &p in positions {
        let mut by_distance: Vec<(f32, usize)> = plan
            .views
            .iter()
            .map(|v| v.position.distance_squared(p))
            .zip(0..)
            .collect();
        by_distance.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for &(_, i) in by_distance.iter().take(bases.max(1)) {
            used[i] = true;
        }
    }
    Plan {
        views: plan
            .views
            .iter()
            .zip(&used)
            .filter(|(_, &u)| u)
            .map(|(v, _)| v.clone())
            .collect(),
        ..plan.clone()
    }
}

/// What one quality and mode cost against the path tracer at its error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Amortized {
    /// The path tracer's samples per pixel and seconds per frame at the
    /// mode's mean error (LRMS or FLIP).
    pub path_spp: f64,
    pub reach: Reach,
    pub path_frame_s: f64,
    /// Synthesis per frame, reading the bases excluded.
    pub synth_frame_s: f64,
    /// The whole bake: planning, radiosity, every planned image.
    pub bake_s: f64,
    /// Reading every planned image once (see [`reading_s`]).
    pub read_s: f64,
    pub break_even: Option<u64>,
    /// Path tracing over the framework for `n` frames.
    pub speedup: f64,
}

/// What reading the bases costs a walk of any length: the run's reading,
/// scaled to every image of the plan. A walk reads each base it uses once
/// while the memory budget holds them, and frames along one path use the
/// same bases in the same order however many there are, so reading is a
/// cost of the walk, as the bake is, not of each frame.
pub fn reading_s(q: &SequenceQuality, m: &ModeRun) -> f64 {
    let unread = q.planned_images() as f64 / q.baked_images.max(1) as f64;
    m.load_s() * unread.max(1.0)
}

/// The framework's cost against the path tracer's at `m`'s mean error in
/// `measure`, amortized over `n` frames; `None` when a time or the error
/// is unknown.
pub fn amortized(
    q: &SequenceQuality,
    m: &ModeRun,
    curve: &[ConvergencePoint],
    n: u64,
    measure: Measure,
) -> Option<Amortized> {
    let (path_frame_s, path_spp, reach) = equal_error_seconds(curve, measure, measure.mean(m)?)?;
    let bake_s = q.full_bake_s()?;
    let read_s = reading_s(q, m);
    let synth_frame_s = m.synth_per_frame_s();
    let fixed_s = bake_s + read_s;
    Some(Amortized {
        path_spp,
        reach,
        path_frame_s,
        synth_frame_s,
        bake_s,
        read_s,
        break_even: break_even(fixed_s, synth_frame_s, path_frame_s),
        speedup: speedup(n, fixed_s, synth_frame_s, path_frame_s),
    })
}

fn paper(q: f32) -> Option<(f64, f64)> {
    crate::eval::experiments::common::table::for_quality(&PAPER, q, |p| p.0).map(|p| (p.1, p.2))
}

/// Writes table.md, qualities.csv, frames.csv, convergence.csv, plots
/// (`flip_vs_time.png` only where FLIP was measured) and strips.
pub fn write(dir: &Path, r: &WalkResults) -> Result<()> {
    convergence_table(&r.convergence)?.write_csv(dir.join("convergence.csv"))?;
    error_vs_time_plots(dir, r)?;
    write_sequence(
        dir,
        &markdown(r)?,
        &qualities_csv(r)?,
        r.args.common.size,
        &r.references[r.preview_frame].radiance,
        &r.qualities,
    )
}

fn reach_note(a: &Amortized) -> &'static str {
    match a.reach {
        Reach::Measured => "",
        Reach::OneSample => " (≤ 1)",
        Reach::Extrapolated => " (extrapolated)",
    }
}

/// The path tracer's samples and time over the walk's `n` frames, the
/// break-even and the speed-up of one comparison, or dashes without one.
fn amortized_cells(a: Option<Amortized>, n: usize) -> [String; 4] {
    let Some(a) = a else {
        return ["—"; 4].map(String::from);
    };
    [
        format!("{}{}", sig(a.path_spp, 3), reach_note(&a)),
        sig(a.path_frame_s * n as f64, 3),
        a.break_even.map_or("never".into(), |b| b.to_string()),
        format!("{:.2}x", a.speedup),
    ]
}

fn markdown(r: &WalkResults) -> Result<String> {
    let a = &r.args;
    let c = &a.common;
    let n = r.times.len();
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# Walk-through: {} (paper Table 5)\n",
        c.scene.display()
    );
    let _ = writeln!(
        md,
        "Path `{}`, {n} frames over t = {} to {} s; fill {}, the {} nearest base views per frame.\n",
        a.path,
        r.times[0],
        r.times[n - 1],
        <&str>::from(a.sequence.fill),
        a.bases
    );
    md.push_str(&differences(
        c,
        r.base_size,
        &format!(
            "{n} frames (the paper: 30); one quality drives planning, simplification, radiosity and \
             the bake, as in the paper; synthesis by this project's reprojection with linear, motion \
             compensated and re-shaded time interpolation (the paper: pinterp and pcomb)"
        ),
    ));
    md.push_str(&notes_md(&r.notes));

    md.push_str("## Scene decomposition and base images\n\n");
    let mut t = Table::new([
        "quality",
        "views",
        "images planned",
        "images baked",
        "planning (s)",
        "simplify + radiosity (s)",
        "base images (s)",
        "per image (s)",
        "bake as run (s)",
        "whole bake (s)",
        "paper (min)",
    ]);
    for q in &r.qualities {
        let timing = q.bake.timing.as_ref();
        t.push([
            q.quality.to_string(),
            q.plan.views.len().to_string(),
            q.planned_images().to_string(),
            q.baked_images.to_string(),
            sig(q.plan_s, 3),
            cell(timing.and_then(|t| t.radiosity_s), 3),
            cell(timing.map(|t| t.render_s), 3),
            cell(timing.and_then(|t| t.per_image_s()), 3),
            cell(q.bake_s(), 3),
            cell(q.full_bake_s(), 3),
            paper(q.quality).map_or("—".into(), |p| sig(p.0, 6)),
        ])?;
    }
    md.push_str(&t.to_markdown());
    md.push_str(
        "\nBake as run: planning, radiosity and the images baked. Whole bake: planning, radiosity and \
         every planned image (those not baked at the measured mean per image).\n",
    );

    let _ = writeln!(md, "\n## Walk-through construction, {n} frames\n");
    let mut t = Table::new([
        "method",
        "synthesis (s)",
        "loading (s)",
        "per frame (s)",
        "mean LRMS",
        "max LRMS",
        "mean bias",
        "mean LRMS, emitters excluded",
        "mean block LRMS",
        "mean block p99",
        "mean FLIP",
        "paper (min)",
    ]);
    let ref_s: Option<f64> = r.references.iter().map(|x| x.seconds).sum();
    let mut row = vec![
        format!("fully rendered: path tracer at {} spp", c.reference_spp),
        cell(ref_s, 3),
        "—".into(),
        cell(ref_s.map(|s| s / n as f64), 3),
    ];
    row.extend(["0"; 7].map(String::from));
    row.push(sig(PAPER_FULLY_RENDERED_MIN, 6));
    t.push(row)?;
    for q in &r.qualities {
        for m in &q.modes {
            t.push([
                format!("q = {}, {}", q.quality, <&str>::from(m.mode)),
                sig(m.synth_s(), 3),
                sig(m.load_s(), 3),
                sig(m.per_frame_s(), 3),
                sig(m.mean_lrms(), 3),
                sig(m.max_lrms(), 3),
                format!("{:+.4}", m.mean_bias()),
                cell(m.mean_lrms_without_emitters(), 3),
                sig(m.mean_block_lrms(), 3),
                sig(m.mean_block_p99(), 3),
                cell(mean_flip(&m.frames), 3),
                paper(q.quality)
                    .filter(|_| m.mode == TimeInterp::Linear)
                    .map_or("—".into(), |p| sig(p.1, 3)),
            ])?;
        }
    }
    md.push_str(&t.to_markdown());
    let _ = writeln!(
        md,
        "\nPer frame: synthesis and loading. The paper's times are for its {PAPER_FRAMES} frames, \
         after bakes of 1,213.53 / 2,894.22 / 7,746.76 min."
    );

    let m_frames = a.amortize_frames;
    let f = r.preview_frame;
    md.push_str("\n## Against the path tracer at equal error\n\n");
    let mut headers = vec!["method".to_string()];
    for what in ["LRMS", "FLIP"] {
        headers.extend([
            format!("equal {what}: path tracer spp"),
            format!("equal {what}: path tracer, all frames (s)"),
            format!("equal {what}: break-even (frames)"),
            format!("equal {what}: speed-up over {m_frames} frames"),
        ]);
    }
    let mut t = Table::new(headers);
    for q in &r.qualities {
        for m in &q.modes {
            let mut row = vec![format!("q = {}, {}", q.quality, <&str>::from(m.mode))];
            for measure in [Measure::Lrms, Measure::Flip] {
                row.extend(amortized_cells(
                    amortized(q, m, &r.convergence, m_frames, measure),
                    n,
                ));
            }
            t.push(row)?;
        }
    }
    md.push_str(&t.to_markdown());
    let _ = writeln!(
        md,
        "\nPath tracer at equal error: the samples per pixel at which the path tracer's error on \
         frame {f} (t = {} s) equals the mode's mean error, LRMS or FLIP, read off its convergence \
         curve (below) on log-log axes, times its measured cost per sample ({} s per spp per frame); \
         \"≤ 1\": one sample is already better; \"extrapolated\": below the curve's last point, LRMS \
         extended as 1/√spp, FLIP along the slope of the curve's last two points; \"—\": not \
         measured (FLIP left out) or a curve that no longer falls. Break-even: the fewest frames for \
         which the whole bake, reading the bases and synthesis cost no more than path tracing every \
         frame to the same error; speed-up: path tracing over the framework for {m_frames} frames, \
         bake included. Reading counts once for the walk (scaled to every planned image), not per \
         frame: a walk reads each base it uses once while they fit in memory, however many frames it \
         has. The two measures can disagree widely: LRMS weighs every pixel alike, FLIP weighs what a \
         viewer notices.",
        r.times[f],
        seconds_per_sample(&r.convergence).map_or("—".into(), |s| sig(s, 3)),
    );

    let _ = writeln!(
        md,
        "\n## Path tracer convergence (frame {f}, t = {} s)\n",
        r.times[f]
    );
    md.push_str(&convergence_table(&r.convergence)?.to_markdown());
    let _ = writeln!(
        md,
        "\n`strip-q<q>.png`: frame {f}, the reference then {}.",
        modes_list(&a.sequence.time_interp)
    );
    Ok(md)
}

fn qualities_csv(r: &WalkResults) -> Result<Table> {
    let mut t = Table::new([
        "quality",
        "mode",
        "views",
        "images_planned",
        "images_baked",
        "planning_s",
        "radiosity_s",
        "render_s",
        "bake_s",
        "whole_bake_s",
        "synth_s",
        "load_s",
        "per_frame_s",
        "mean_lrms",
        "max_lrms",
        "mean_lrms_without_emitters",
        "mean_block_lrms",
        "mean_block_p99",
        "mean_flip",
        "path_spp",
        "path_reach",
        "path_frame_s",
        "break_even_frames",
        "speedup",
        "path_spp_flip",
        "path_reach_flip",
        "path_frame_s_flip",
        "break_even_frames_flip",
        "speedup_flip",
    ]);
    let opt = |x: Option<f64>| x.map_or(String::new(), |x| x.to_string());
    for q in &r.qualities {
        let timing = q.bake.timing.as_ref();
        for m in &q.modes {
            let mut row = vec![
                q.quality.to_string(),
                <&str>::from(m.mode).to_string(),
                q.plan.views.len().to_string(),
                q.planned_images().to_string(),
                q.baked_images.to_string(),
                q.plan_s.to_string(),
                opt(timing.and_then(|t| t.radiosity_s)),
                opt(timing.map(|t| t.render_s)),
                opt(q.bake_s()),
                opt(q.full_bake_s()),
                m.synth_s().to_string(),
                m.load_s().to_string(),
                m.per_frame_s().to_string(),
                m.mean_lrms().to_string(),
                m.max_lrms().to_string(),
                opt(m.mean_lrms_without_emitters()),
                m.mean_block_lrms().to_string(),
                m.mean_block_p99().to_string(),
                opt(mean_flip(&m.frames)),
            ];
            for measure in [Measure::Lrms, Measure::Flip] {
                let am = amortized(q, m, &r.convergence, r.args.amortize_frames, measure);
                row.extend([
                    opt(am.map(|a| a.path_spp)),
                    am.map_or(String::new(), |a| format!("{:?}", a.reach).to_lowercase()),
                    opt(am.map(|a| a.path_frame_s)),
                    am.and_then(|a| a.break_even)
                        .map_or(String::new(), |b| b.to_string()),
                    opt(am.map(|a| a.speedup)),
                ]);
            }
            t.push(row)?;
        }
    }
    Ok(t)
}

/// Mean error against seconds per frame, in LRMS (`error_vs_time.png`)
/// and, where measured, FLIP (`flip_vs_time.png`): the path tracer's
/// convergence curve, and each quality and mode with its whole bake and
/// reading amortized over the walk's frames and over `--amortize-frames`.
/// Where a mode's point lies below the curve at its time, it beats the
/// path tracer there.
fn error_vs_time_plots(dir: &Path, r: &WalkResults) -> Result<()> {
    let n = r.times.len() as u64;
    for (measure, file, label) in [
        (Measure::Lrms, "error_vs_time.png", "mean LRMS"),
        (Measure::Flip, "flip_vs_time.png", "mean FLIP"),
    ] {
        let curve = convergence_series(&r.convergence, measure);
        if curve.points.is_empty() {
            continue;
        }
        let mut series = vec![curve];
        for frames in [n, r.args.amortize_frames] {
            for &mode in &r.args.sequence.time_interp {
                series.push(Series {
                    label: format!("{}, bake over {frames} frames", <&str>::from(mode)),
                    points: r
                        .qualities
                        .iter()
                        .filter_map(|q| {
                            let m = q.modes.iter().find(|m| m.mode == mode)?;
                            let fixed = q.full_bake_s()? + reading_s(q, m);
                            let per_frame = fixed / frames as f64 + m.synth_per_frame_s();
                            Some((per_frame, measure.mean(m)?))
                        })
                        .collect(),
                });
            }
        }
        plot::write_png(
            dir.join(file),
            &Plot {
                title: "Walk-through: error against time per frame",
                x_label: "seconds per frame (whole bake and reading amortized)",
                y_label: label,
                scale: Scale::LogLog,
                series: &series,
            },
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Backend;
    use crate::eval::experiments::common::sequence::frames_csv;
    use crate::eval::experiments::common::setup::{BakeCost, BakeTiming};
    use crate::eval::experiments::common::synthesize::SynthFrame;
    use crate::eval::metrics::ImageError;
    use crate::plan::PlannedView;
    use crate::synth::{Blend, Fill};

    fn error(lrms: f64) -> ImageError {
        ImageError {
            lrms,
            bias: 0.0,
            block_lrms: 0.8 * lrms,
            block_p99: 2.0 * lrms,
            pixels: 4,
        }
    }

    /// One quality whose numbers are easy to follow by hand: a bake of
    /// 2 s planning + 10 s radiosity + 4 images at 10 s, frames of 1 s at
    /// LRMS 0.25 and FLIP 0.05, a path tracer at 0.1 s per spp with LRMS
    /// 1/√spp and FLIP 0.4 halving at every 4x.
    fn results() -> WalkResults {
        let view = |x: f32| PlannedView {
            position: Vec3::new(x, 0.0, 0.0),
            times: vec![0.0, 1.0],
        };
        let frame = |i: usize| SynthFrame {
            frame: i,
            time: i as f32,
            synth_s: 0.5,
            load_s: 0.5,
            images: 4,
            holes: 0,
            filled: 0,
            error: error(0.25),
            without_emitters: None,
            flip: Some(0.05),
        };
        let quality = SequenceQuality {
            quality: 0.3,
            plan: Plan {
                views: vec![view(0.0), view(1.0)],
                ..Plan::default()
            },
            plan_s: 2.0,
            baked_views: 2,
            baked_images: 4,
            bake: BakeCost {
                timing: Some(BakeTiming {
                    radiosity_s: Some(10.0),
                    render_s: 40.0,
                    rendered: 4,
                    images: 4,
                    samples: 0,
                    rays: 0,
                }),
                reused: false,
            },
            modes: vec![ModeRun {
                mode: TimeInterp::Linear,
                frames: vec![frame(0), frame(1)],
                preview: vec![Vec3::ONE; 4],
            }],
        };
        WalkResults {
            args: WalkthroughArgs {
                common: CommonArgs {
                    scene: "scenes/cornell-box/scene.toml".into(),
                    quality: vec![crate::quality::Quality::new(0.3).unwrap()],
                    out: "out".into(),
                    size: (2, 2),
                    reference_spp: 256,
                    base_spp: 4,
                    base_size: Some(16),
                    supersample: 2,
                    blend: Blend::Average,
                    backend: Backend::Bvh,
                    view_fitness: crate::plan::ViewFitness::Ids,
                    indirect: crate::bake::IndirectSource::Radiosity,
                    no_flip: true,
                },
                path: "walk".into(),
                sequence: SequenceArgs {
                    frames: Some(2),
                    time_interp: vec![TimeInterp::Linear],
                    fill: Fill::Both,
                },
                bases: 4,
                bake_views: BakeViews::All,
                amortize_frames: 300,
            },
            times: vec![0.0, 1.0],
            preview_frame: 1,
            base_size: 16,
            references: (0..2)
                .map(|_| Reference {
                    radiance: vec![Vec3::ONE; 4],
                    seconds: Some(25.6),
                    reused: false,
                })
                .collect(),
            convergence: [1, 4, 16, 64]
                .map(|spp| ConvergencePoint {
                    spp,
                    seconds: 0.1 * spp as f64,
                    error: error(1.0 / (spp as f64).sqrt()),
                    flip: Some(0.4 / (spp as f64).sqrt()),
                })
                .to_vec(),
            qualities: vec![quality],
            notes: Vec::new(),
            out: "out".into(),
        }
    }

    #[test]
    fn the_table_amortizes_the_whole_bake() {
        let r = results();
        let q = &r.qualities[0];
        assert_eq!(q.full_bake_s(), Some(52.0));
        // LRMS 0.25 is the path tracer's at 16 spp: 1.6 s a frame against
        // 0.5 s of synthesis, after 52 s of bake and 1 s of reading, so
        // 53 / 1.1 = 48.2: 49 frames; over 300 frames 480 s / (53 + 150) s.
        let a = amortized(q, &q.modes[0], &r.convergence, 300, Measure::Lrms).unwrap();
        assert!((a.path_spp - 16.0).abs() < 1e-9, "{a:?}");
        assert!((a.path_frame_s - 1.6).abs() < 1e-9, "{a:?}");
        assert!((a.read_s - 1.0).abs() < 1e-9, "{a:?}");
        assert_eq!(a.break_even, Some(49));
        // FLIP 0.05 is the path tracer's at 64 spp: 6.4 s a frame, so
        // 53 / 5.9 = 8.98: 9 frames; over 300 frames 1920 s / 203 s.
        let f = amortized(q, &q.modes[0], &r.convergence, 300, Measure::Flip).unwrap();
        assert!((f.path_spp - 64.0).abs() < 1e-9, "{f:?}");
        assert!((f.path_frame_s - 6.4).abs() < 1e-9, "{f:?}");
        assert_eq!(f.break_even, Some(9));
        let md = markdown(&r).unwrap();
        let rows: Vec<&str> = md
            .lines()
            .filter(|l| l.starts_with("| q = 0.3, linear |"))
            .collect();
        assert_eq!(rows.len(), 2, "{md}");
        // Construction: times, errors (block LRMS and p99 beside LRMS and
        // FLIP) and the paper's minutes.
        assert_eq!(
            rows[0],
            "| q = 0.3, linear | 1.00 | 1.00 | 1.00 | 0.250 | 0.250 | +0.0000 | — | 0.200 | 0.500 \
             | 0.0500 | 90.0 |"
        );
        // At equal LRMS, then at equal FLIP.
        assert_eq!(
            rows[1],
            "| q = 0.3, linear | 16.0 | 3.20 | 49 | 2.36x | 64.0 | 12.8 | 9 | 9.46x |"
        );
        assert!(md.contains("equal FLIP: break-even (frames)"), "{md}");
        // Without FLIP the comparison at equal FLIP is left empty.
        let mut no_flip = r.clone();
        for m in &mut no_flip.qualities[0].modes {
            for fr in &mut m.frames {
                fr.flip = None;
            }
        }
        for p in &mut no_flip.convergence {
            p.flip = None;
        }
        let md = markdown(&no_flip).unwrap();
        assert!(
            md.contains("| q = 0.3, linear | 16.0 | 3.20 | 49 | 2.36x | — | — | — | — |"),
            "{md}"
        );
        let csv = qualities_csv(&r).unwrap();
        let col = |name: &str| csv.headers.iter().position(|h| h == name).unwrap();
        assert_eq!(csv.rows[0][col("break_even_frames")], "49");
        assert_eq!(csv.rows[0][col("break_even_frames_flip")], "9");
        assert_eq!(csv.rows[0][col("mean_block_p99")], "0.5");
        // Half of the plan baked: its reading counts for all of it.
        let mut half = q.clone();
        half.baked_images = 2;
        assert!((reading_s(&half, &half.modes[0]) - 2.0).abs() < 1e-9);
        // The phases: 2 + 10 + 40 s, the paper's 1,213.53 minutes beside.
        assert!(
            md.contains("| 0.3 | 2 | 4 | 4 | 2.00 | 10.0 | 40.0 | 10.0 | 52.0 | 52.0 | 1213.53 |"),
            "{md}"
        );
        assert!(
            md.contains("fully rendered: path tracer at 256 spp | 51.2 |"),
            "{md}"
        );
        let frames = frames_csv(&r.qualities).unwrap();
        assert_eq!(frames.rows.len(), 2);
        assert_eq!(qualities_csv(&r).unwrap().rows.len(), 1);
    }

    #[test]
    fn only_the_views_frames_use_are_kept_in_order() {
        let view = |x: f32| PlannedView {
            position: Vec3::new(x, 0.0, 0.0),
            times: vec![0.0, 1.0],
        };
        let plan = Plan {
            views: vec![view(0.0), view(4.0), view(1.0), view(3.0), view(2.0)],
            ..Plan::default()
        };
        // Frames near 0.2 and 0.9 take views at 0 and 1; near 3.6, 4 and 3.
        let cut = used_views(
            &plan,
            &[Vec3::new(0.2, 0.0, 0.0), Vec3::new(3.6, 0.0, 0.0)],
            2,
        );
        let xs: Vec<f32> = cut.views.iter().map(|v| v.position.x).collect();
        assert_eq!(xs, [0.0, 4.0, 1.0, 3.0]);
        // Midway between two views the lower index wins, as in synthesis.
        let cut = used_views(&plan, &[Vec3::new(0.5, 0.0, 0.0)], 1);
        assert_eq!(cut.views.len(), 1);
        assert_eq!(cut.views[0].position.x, 0.0);
    }
}
