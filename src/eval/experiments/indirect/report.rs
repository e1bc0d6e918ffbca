//! The report of `experiment indirect`: `table.md` laid out like the
//! paper's Tables 1 and 2 (with the paper's figures beside ours),
//! `frames.csv`, `convergence.csv`, two plots and preview images.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use glam::Vec3;

use super::{FrameResult, IndirectResults, PathTracerRun, QualityRun};
use crate::eval::experiments::common::convergence::Measure;
use crate::eval::experiments::common::convergence::{convergence_series, convergence_table};
use crate::eval::experiments::common::plot::{self, Plot, Scale, Series};
use crate::eval::experiments::common::table::{mean, times_list};
use crate::eval::experiments::common::table::{sig, Table};
use crate::eval::sheet::exposure_for;
use crate::image;

/// The paper's relative LRMS of its wavelet-radiosity (WR) images at
/// qualities 0.3, 0.6 and 0.9: Table 1 (studio, geometric simplification)
/// and Table 2 (Cornell box, temporal interpolation), both against
/// Radiance's high-quality setting.
const PAPER: [(f32, f64, f64); 3] = [
    (0.3, 0.381, 0.147),
    (0.6, 0.340, 0.138),
    (0.9, 0.339, 0.119),
];

fn paper(q: f32) -> Option<(f64, f64)> {
    crate::eval::experiments::common::table::for_quality(&PAPER, q, |p| p.0).map(|p| (p.1, p.2))
}

/// Writes every output file of `r` into `dir`.
pub fn write(dir: &Path, r: &IndirectResults) -> Result<()> {
    let md = markdown(r)?;
    let path = dir.join("table.md");
    std::fs::write(&path, md).with_context(|| format!("writing {}", path.display()))?;
    frames_csv(r)?.write_csv(dir.join("frames.csv"))?;
    convergence_csv(r)?.write_csv(dir.join("convergence.csv"))?;
    plots(dir, r)?;
    previews(dir, r)
}

fn max(xs: impl Iterator<Item = f64>) -> f64 {
    xs.fold(f64::NAN, f64::max)
}

/// Mean and maximum LRMS, mean bias, mean block LRMS and block p99, mean
/// and maximum FLIP of some frames.
fn errors(frames: &[FrameResult]) -> [String; 7] {
    let flip = |f: fn(&mut dyn Iterator<Item = f64>) -> f64| {
        let mut it = frames.iter().filter_map(|x| x.flip);
        if frames.iter().any(|x| x.flip.is_none()) {
            "—".to_string()
        } else {
            sig(f(&mut it), 3)
        }
    };
    [
        sig(mean(frames.iter().map(|f| f.error.lrms)), 3),
        sig(max(frames.iter().map(|f| f.error.lrms)), 3),
        format!("{:+.4}", mean(frames.iter().map(|f| f.error.bias))),
        sig(mean(frames.iter().map(|f| f.error.block_lrms)), 3),
        sig(mean(frames.iter().map(|f| f.error.block_p99)), 3),
        flip(|it| mean(it)),
        flip(|it| max(it)),
    ]
}

fn pt_label(p: &PathTracerRun) -> String {
    let qs: Vec<String> = p.matches.iter().map(|q| q.to_string()).collect();
    format!(
        "path tracer {} spp (time of q = {}{})",
        p.spp,
        qs.join(", "),
        if p.capped { "; capped" } else { "" }
    )
}

fn markdown(r: &IndirectResults) -> Result<String> {
    let a = &r.args;
    let mut md = String::new();
    let n = r.times.len();
    let _ = writeln!(md, "# Indirect illumination: {}\n", r.args.scene.display());
    let _ = writeln!(
        md,
        "Camera `{}`, {}x{}, {n} frame(s) at t = {} s; ray engine {}; multipass renderer at {} spp; \
         references path-traced at {} spp; {} threads. Times are wall-clock seconds.\n",
        a.camera,
        a.size.0,
        a.size.1,
        times_list(&r.times),
        a.backend,
        a.spp,
        a.reference_spp,
        rayon::current_num_threads()
    );
    md.push_str(crate::eval::experiments::common::sequence::ERRORS_MD);
    if !r.notes.is_empty() {
        md.push_str("Stages left out and notes:\n\n");
        for note in &r.notes {
            let _ = writeln!(md, "- {note}");
        }
        md.push('\n');
    }

    md.push_str("## Geometric simplification (paper Table 1, scene decomposition)\n\n");
    let mut t = Table::new([
        "quality",
        "initial surfaces",
        "pruned surfaces",
        "final surfaces",
        "records",
        "visibility rays",
        "time (s)",
    ]);
    for q in &r.qualities {
        let s = &q.simplify;
        t.push([
            q.quality.to_string(),
            s.initial_surfaces.to_string(),
            s.pruned_surfaces.to_string(),
            s.final_surfaces.to_string(),
            q.records.to_string(),
            s.visibility_rays.to_string(),
            sig(q.simplify_s, 3),
        ])?;
    }
    md.push_str(&t.to_markdown());

    md.push_str("\n## Analysis (paper Table 1)\n\n");
    let mut t = Table::new([
        "image",
        "time, all frames (s)",
        "mean LRMS",
        "paper LRMS (studio)",
    ]);
    let ref_s: Option<f64> = r.references.iter().map(|x| x.seconds).sum();
    t.push([
        format!("path tracer reference ({} spp)", a.reference_spp),
        ref_s.map_or("unknown (cached)".to_string(), |s| sig(s, 3)),
        "0".to_string(),
        "0.000".to_string(),
    ])?;
    for p in &r.equal_time {
        t.push([
            pt_label(p),
            sig(p.total_s(), 3),
            sig(mean(p.frames.iter().map(|f| f.error.lrms)), 3),
            "—".to_string(),
        ])?;
    }
    for q in &r.qualities {
        t.push([
            format!("radiosity + multipass, q = {}", q.quality),
            sig(q.total_s(), 3),
            sig(mean(q.frames.iter().map(|f| f.error.lrms)), 3),
            paper(q.quality).map_or("—".to_string(), |p| format!("{:.3}", p.0)),
        ])?;
    }
    md.push_str(&t.to_markdown());
    md.push_str(
        "\nThe paper's Table 1 is for its 70,000-surface studio, against Radiance HQ \
         (Radiance typical: 0.360).\n",
    );

    md.push_str("\n## Temporal interpolation of indirect illumination (paper Table 2)\n\n");
    let mut t = Table::new([
        "method",
        "solves",
        "solve times (s)",
        "iterations",
        "max residual",
        "scene decomposition (s)",
        "indirect generation (s)",
        "interpolation (s)",
        "rendering (s)",
        "total (s)",
        "mean LRMS",
        "max LRMS",
        "mean bias",
        "mean block LRMS",
        "mean block p99",
        "mean FLIP",
        "max FLIP",
        "paper LRMS (Cornell box)",
    ]);
    for q in &r.qualities {
        t.push(table2_row(q))?;
    }
    for p in &r.equal_time {
        let mut row = vec![pt_label(p)];
        row.extend(["—", "—", "—", "—", "0", "0", "0"].map(String::from));
        row.push(sig(p.total_s(), 3));
        row.push(sig(p.total_s(), 3));
        row.extend(errors(&p.frames));
        row.push("—".to_string());
        t.push(row)?;
    }
    md.push_str(&t.to_markdown());
    md.push_str(
        "\nThe paper's Table 2 is for a 30-frame Cornell box sequence against Radiance HQ \
         (Radiance typical: 0.183).\n",
    );

    let f = r.preview_frame;
    let _ = writeln!(
        md,
        "\n## Path tracer convergence (frame {f}, t = {} s)\n",
        r.times[f]
    );
    md.push_str(&convergence_csv(r)?.to_markdown());
    Ok(md)
}

fn table2_row(q: &QualityRun) -> Vec<String> {
    let iterations: usize = q.solves.iter().map(|(_, s)| s.iterations).sum();
    let residual = q.solves.iter().map(|(_, s)| s.residual).fold(0.0, f64::max);
    let mut row = vec![
        format!("radiosity + multipass, q = {}", q.quality),
        q.solves.len().to_string(),
        times_list(&q.solves.iter().map(|(t, _)| *t).collect::<Vec<_>>()),
        iterations.to_string(),
        sig(residual, 2),
        sig(q.scene_decomposition_s(), 3),
        sig(q.indirect_generation_s(), 3),
        sig(q.interpolation_s(), 3),
        sig(q.render_s(), 3),
        sig(q.total_s(), 3),
    ];
    row.extend(errors(&q.frames));
    row.push(paper(q.quality).map_or("—".to_string(), |p| format!("{:.3}", p.1)));
    row
}

fn frames_csv(r: &IndirectResults) -> Result<Table> {
    let mut t = Table::new([
        "method",
        "quality",
        "spp",
        "frame",
        "time_s",
        "lrms",
        "bias",
        "block_lrms",
        "block_p99",
        "flip",
        "interpolation_s",
        "render_s",
    ]);
    let mut rows = |method: &str, quality: String, spp: u32, frames: &[FrameResult]| {
        for f in frames {
            t.push([
                method.to_string(),
                quality.clone(),
                spp.to_string(),
                f.frame.to_string(),
                f.time.to_string(),
                f.error.lrms.to_string(),
                f.error.bias.to_string(),
                f.error.block_lrms.to_string(),
                f.error.block_p99.to_string(),
                f.flip.map_or(String::new(), |x| x.to_string()),
                f.interpolation_s.to_string(),
                f.render_s.to_string(),
            ])?;
        }
        anyhow::Ok(())
    };
    for q in &r.qualities {
        rows("multipass", q.quality.to_string(), r.args.spp, &q.frames)?;
    }
    for p in &r.equal_time {
        let qs: Vec<String> = p.matches.iter().map(|q| q.to_string()).collect();
        rows("path-tracer", qs.join(";"), p.spp, &p.frames)?;
    }
    Ok(t)
}

fn convergence_csv(r: &IndirectResults) -> Result<Table> {
    convergence_table(&r.convergence)
}

fn plots(dir: &Path, r: &IndirectResults) -> Result<()> {
    let per_frame = |label: String, frames: &[FrameResult]| Series {
        label,
        points: frames
            .iter()
            .map(|f| (f.time as f64, f.error.lrms))
            .collect(),
    };
    let mut series: Vec<Series> = r
        .qualities
        .iter()
        .map(|q| per_frame(format!("q = {}", q.quality), &q.frames))
        .collect();
    series.extend(
        r.equal_time
            .iter()
            .map(|p| per_frame(pt_label(p), &p.frames)),
    );
    plot::error_per_frame(dir, &series)?;

    let n = r.times.len() as f64;
    let mut series = vec![convergence_series(&r.convergence, Measure::Lrms)];
    series.extend(r.qualities.iter().map(|q| Series {
        label: format!("q = {}", q.quality),
        points: vec![(q.total_s() / n, mean(q.frames.iter().map(|f| f.error.lrms)))],
    }));
    series.push(Series {
        label: "path tracer at equal time".to_string(),
        points: r
            .equal_time
            .iter()
            .map(|p| (p.total_s() / n, mean(p.frames.iter().map(|f| f.error.lrms))))
            .collect(),
    });
    plot::write_png(
        dir.join("error_vs_time.png"),
        &Plot {
            title: "Error against time per frame",
            x_label: "seconds per frame (all stages amortized)",
            y_label: "mean LRMS",
            scale: Scale::LogLog,
            series: &series,
        },
    )
}

/// PNG previews of one frame, all at the exposure that puts the reference's
/// mean luminance at middle grey, so they compare directly.
fn previews(dir: &Path, r: &IndirectResults) -> Result<()> {
    let (w, h) = r.args.size;
    let reference = &r.references[r.preview_frame].radiance;
    let exposure = exposure_for(reference);
    let write = |name: String, radiance: &[Vec3]| {
        image::write_png_preview(dir.join(name), w, h, radiance, exposure)
    };
    write("preview-reference.png".to_string(), reference)?;
    for q in &r.qualities {
        write(format!("preview-q{}.png", q.quality), &q.preview)?;
    }
    for p in &r.equal_time {
        write(format!("preview-path-tracer-{}spp.png", p.spp), &p.preview)?;
    }
    Ok(())
}
