//! `rangewalk experiment views`: view reconstruction along a 1D view
//! subspace (the paper's Table 3, §5.2.1).
//!
//! For each quality the segment is planned (id-image fitness, adaptive
//! subdivision), a target view is placed between two adjacent bases of the
//! plan, those two bases are baked (as the paper rendered only the pair
//! flanking its chosen view) and the target is synthesized from them with
//! each of the four fill modes. A sphere base baked at the target itself
//! and resampled to the target's view measures the error of resampling
//! alone (the paper's "resampled radiance" row). Every image is compared
//! with a path-traced reference of the target view.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{ensure, Context, Result};
use glam::Vec3;

use crate::eval::experiments::common::plot::{self, Plot, Scale, Series};
use crate::eval::experiments::common::sequence::{differences, notes_md};
use crate::eval::experiments::common::setup::{
    bake_cached, engine, plan_timed, quality_dir, references_of, BakeCost, BakeTiming, CommonArgs,
    Shot,
};
use crate::eval::experiments::common::staging::{Staging, BAKES_DIR, REFERENCE_DIR};
use crate::eval::experiments::common::synthesize::{emitter_free, synthesize, SynthFrame, Truth};
use crate::eval::experiments::common::table::cell;
use crate::eval::experiments::common::table::{sig, Table};
use crate::eval::metrics::ImageError;
use crate::eval::reference::Reference;
use crate::eval::sheet::{exposure_for, write_strip};
use crate::plan::{Plan, PlannedView};
use crate::radiosity::lookup::IrradianceCache;
use crate::render::{multipass, RenderSettings};
use crate::scene::ViewSpace;
use crate::synth::{Fill, Options, TimeInterp};

/// The fill modes, in pinterp's order.
pub const FILLS: [Fill; 4] = [Fill::None, Fill::Foreground, Fill::Background, Fill::Both];

/// The paper's Table 3: relative LRMS of the reconstructions at qualities
/// 0.3, 0.6, 0.9, and of the resampled radiance.
const PAPER: [(f32, f64); 3] = [(0.3, 0.638), (0.6, 0.625), (0.9, 0.117)];
const PAPER_RESAMPLED: f64 = 0.120;

/// What `rangewalk experiment views` takes.
#[derive(Clone, Debug)]
pub struct ViewsArgs {
    pub common: CommonArgs,
    /// Named camera whose view direction and field of view the target view
    /// takes.
    pub camera: String,
    /// The 1D view subspace, `x,y,z:x,y,z` [default: the scene's segment,
    /// or the line through the middle of its rectangle or box along the
    /// longest side].
    pub view_segment: Option<ViewSpace>,
    /// Put the target view at this fraction of the segment for every
    /// quality [default: for each quality, midway between the two adjacent
    /// bases whose middle is nearest the segment's].
    pub target: Option<f32>,
}

/// One synthesized target view.
#[derive(Clone, Debug)]
pub struct FillRun {
    pub fill: Fill,
    pub frame: SynthFrame,
    pub image: Vec<Vec3>,
}

/// The target view rendered directly by the multipass renderer with the
/// bases' samples and radiosity: the bases' own error, without any
/// resampling.
#[derive(Clone, Debug)]
pub struct DirectRun {
    pub seconds: f64,
    pub error: ImageError,
    pub without_emitters: Option<ImageError>,
    pub flip: Option<f64>,
    pub image: Vec<Vec3>,
}

/// Everything measured for one quality.
#[derive(Clone, Debug)]
pub struct ViewsQuality {
    pub quality: f32,
    /// The whole segment's plan.
    pub plan: Plan,
    pub plan_s: f64,
    /// Each planned view's position along the segment, in [0, 1].
    pub along: Vec<f32>,
    /// The two plan views flanking the target.
    pub pair: [usize; 2],
    /// The target's position along the segment, and in the scene.
    pub target_along: f32,
    pub target: Vec3,
    pub bake: BakeCost,
    /// The sphere base at the target.
    pub resampled_bake: BakeCost,
    pub reference: Reference,
    pub synthesized: Vec<FillRun>,
    pub resampled: Vec<FillRun>,
    pub direct: DirectRun,
}

impl ViewsQuality {
    /// Distance between the two bases.
    pub fn spacing(&self) -> f32 {
        self.plan.views[self.pair[0]]
            .position
            .distance(self.plan.views[self.pair[1]].position)
    }
}

/// The experiment's measurements.
#[derive(Clone, Debug)]
pub struct ViewsResults {
    pub args: ViewsArgs,
    pub segment: (Vec3, Vec3),
    pub time: f32,
    pub base_size: u32,
    pub qualities: Vec<ViewsQuality>,
    pub notes: Vec<String>,
    pub out: PathBuf,
}

/// Runs the experiment and writes its report to `args.common.out`.
pub fn run(args: &ViewsArgs) -> Result<ViewsResults> {
    let c = &args.common;
    let setup = c.setup()?;
    if let Some(f) = args.target {
        ensure!(
            (0.0..=1.0).contains(&f),
            "--target {f} must lie in [0, 1] (a fraction of the segment)"
        );
    }
    let mut scene = setup.scene;
    let mut notes = setup.notes;
    let desc = scene.camera(&args.camera)?.clone();
    let segment = match args.view_segment {
        Some(ViewSpace::Segment { a, b }) => (a, b),
        Some(_) => unreachable!("--view-segment parses as a segment"),
        None => {
            let space = scene.view_space.with_context(|| {
                format!(
                    "{} has no view space: pass --view-segment",
                    scene.source.display()
                )
            })?;
            let s = default_segment(&space);
            if space.dimensions() > 1 {
                notes.push(format!(
                    "1D view subspace: the segment from {} to {} through the middle of the scene's {}D view space along its longest side",
                    s.0,
                    s.1,
                    space.dimensions()
                ));
            }
            s
        }
    };
    ensure!(
        segment.0.distance(segment.1) > 0.0,
        "the view segment has no length"
    );
    scene.view_space = Some(ViewSpace::Segment {
        a: segment.0,
        b: segment.1,
    });
    let time = scene.animation.start;
    if !scene.is_static() {
        notes.push(format!(
            "the scene is animated: everything at t = {time} s, one base image per view"
        ));
    }
    notes.push(
        "only the two base views flanking the target are baked, as the paper rendered only that pair; \
         the plan's other views are counted, not rendered"
            .to_string(),
    );
    notes.push(
        "resampled radiance: a sphere base baked at the target itself (same quality, size and samples) \
         and resampled to the target's view by the same synthesis"
            .to_string(),
    );
    let (w, h) = c.size;
    let staging = Staging::begin(&c.out)?;
    let bakes = staging.dir().join(BAKES_DIR);
    let refs_dir = staging.dir().join(REFERENCE_DIR);
    let mut engine = engine(&scene, c.backend)?;
    let mut runs = Vec::new();
    for &q in &setup.qualities {
        let tag = format!("q = {}", q.get());
        engine.set_transforms(&scene.at(time))?;
        let (plan, plan_s) = plan_timed(&scene, engine.as_mut(), q, c.view_fitness)?;
        let along: Vec<f32> = plan
            .views
            .iter()
            .map(|v| along_segment(segment, v.position))
            .collect();
        let (i, j, target_along) = flanking(&along, args.target)
            .with_context(|| format!("{tag}: no two base views flank the target"))?;
        let target = segment.0.lerp(segment.1, target_along);
        eprintln!(
            "{tag}: {} base view(s) ({plan_s:.3} s); target at {target} between {} and {}",
            plan.views.len(),
            plan.views[i].position,
            plan.views[j].position
        );
        let settings = c.bake_settings(q, setup.base_size);
        let pair_plan = Plan {
            views: vec![plan.views[i].clone(), plan.views[j].clone()],
            ..plan.clone()
        };
        let at_target = Plan {
            views: vec![PlannedView {
                position: target,
                times: vec![time],
            }],
            ..plan.clone()
        };
        let mut bake = |prefix: &str, plan: &Plan| {
            let dir = bakes.join(quality_dir(prefix, q));
            bake_cached(&scene, &dir, &settings, plan, engine.as_mut())
        };
        let pair = bake("", &pair_plan)?;
        let own = bake("target-", &at_target)?;
        let camera = crate::scene::CameraDesc {
            position: target,
            ..desc.clone()
        }
        .perspective(w, h)?;
        let shot = Shot {
            camera,
            time,
            name: format!(
                "{}-at-{:.4}_{:.4}_{:.4}",
                args.camera, target.x, target.y, target.z
            ),
        };
        let reference = references_of(
            &scene,
            engine.as_mut(),
            std::slice::from_ref(&shot),
            c.reference_spp,
            &refs_dir,
        )?
        .remove(0);
        let mask = emitter_free(&scene, engine.as_mut(), &shot.camera, time)?;
        let truth = Truth {
            radiance: &reference.radiance,
            size: (shot.camera.width, shot.camera.height),
            emitter_free: mask.as_deref(),
        };
        let fills = |bake: &crate::bake::Bake, what: &str| -> Result<Vec<FillRun>> {
            FILLS
                .iter()
                .map(|&fill| {
                    let opts = Options {
                        fill,
                        time_interp: TimeInterp::Linear,
                        bases: 2,
                        supersample: c.supersample,
                        blend: c.blend,
                        ..Options::default()
                    };
                    let mut r = synthesize(
                        &scene,
                        bake,
                        std::slice::from_ref(&shot),
                        &[truth],
                        &opts,
                        setup.flip.as_ref(),
                        &format!("{tag} {what}, fill {}", <&str>::from(fill)),
                    )?;
                    Ok(FillRun {
                        fill,
                        frame: r.frames.remove(0),
                        image: r.images.remove(0),
                    })
                })
                .collect()
        };
        let synthesized = fills(&pair.bake, "from the pair")?;
        let resampled = fills(&own.bake, "resampled")?;
        let direct = render_direct(
            &scene,
            engine.as_mut(),
            &own.bake,
            &shot,
            c.base_spp,
            &truth,
            setup.flip.as_ref(),
        )
        .with_context(|| format!("{tag}: the multipass render of the target"))?;
        runs.push(ViewsQuality {
            quality: q.get(),
            plan,
            plan_s,
            along,
            pair: [i, j],
            target_along,
            target,
            bake: pair.cost(),
            resampled_bake: own.cost(),
            reference,
            synthesized,
            resampled,
            direct,
        });
    }
    let references: Vec<Reference> = runs.iter().map(|r| r.reference.clone()).collect();
    notes.extend(crate::eval::reference::reuse_note(&references));
    if runs
        .iter()
        .any(|r| r.bake.reused || r.resampled_bake.reused)
    {
        notes.push(
            "bakes reused from an earlier run: their times are the ones that run recorded"
                .to_string(),
        );
    }
    let mut results = ViewsResults {
        args: args.clone(),
        segment,
        time,
        base_size: setup.base_size,
        qualities: runs,
        notes,
        out: c.out.clone(),
    };
    write(staging.dir(), &results)?;
    results.out = staging.finish()?;
    Ok(results)
}

/// The multipass render of `shot` with `bake`'s radiosity records and
/// samples per pixel, compared with the reference.
fn render_direct(
    scene: &crate::scene::Scene,
    engine: &mut dyn crate::accel::InstancedEngine,
    bake: &crate::bake::Bake,
    shot: &Shot,
    spp: u32,
    truth: &Truth,
    flip: Option<&crate::eval::flip::Flip>,
) -> Result<DirectRun> {
    let (simplified, series) =
        crate::radiosity::store::load(&bake.dir.join(crate::bake::manifest::RADIOSITY))?;
    let cache = IrradianceCache::new(&simplified, &series.indirect_at(shot.time))?;
    engine.set_transforms(&scene.at(shot.time))?;
    let settings = RenderSettings {
        spp,
        max_depth: None,
        seed: 1,
    };
    let (img, stats) =
        multipass::render(scene, &*engine, &shot.camera, shot.time, &settings, &cache)?;
    let (error, without_emitters) = truth.compare(&img)?;
    let flip = match flip {
        Some(f) => Some(f.hdr_mean(img.width, img.height, truth.radiance, &img.radiance)?),
        None => None,
    };
    eprintln!(
        "multipass render of the target at {spp} spp: LRMS {:.4} ({:.3} s)",
        error.lrms, stats.seconds
    );
    Ok(DirectRun {
        seconds: stats.seconds,
        error,
        without_emitters,
        flip,
        image: img.radiance,
    })
}

/// The 1D subspace of a view space: the segment itself, or the line
/// through the middle of a rectangle or box along its longest side.
pub fn default_segment(space: &ViewSpace) -> (Vec3, Vec3) {
    match *space {
        ViewSpace::Segment { a, b } => (a, b),
        ViewSpace::Rectangle { min, max } | ViewSpace::Box { min, max } => {
            let mid = 0.5 * (min + max);
            let extent = max - min;
            let k = (0..3)
                .max_by(|&i, &j| extent[i].total_cmp(&extent[j]))
                .expect("three axes");
            let (mut a, mut b) = (mid, mid);
            a[k] = min[k];
            b[k] = max[k];
            (a, b)
        }
    }
}

/// Where `p` lies along the segment `(a, b)`: 0 at `a`, 1 at `b`.
pub fn along_segment((a, b): (Vec3, Vec3), p: Vec3) -> f32 {
    let ab = b - a;
    (p - a).dot(ab) / ab.length_squared()
}

/// The two adjacent bases (indices into `along`, the bases' positions
/// along the segment) between which the target lies, and the target's
/// position: `at`, or without it the middle of the adjacent pair whose
/// middle is nearest the segment's (the first of two equally near).
pub fn flanking(along: &[f32], at: Option<f32>) -> Option<(usize, usize, f32)> {
    let mut order: Vec<usize> = (0..along.len()).collect();
    order.sort_by(|&i, &j| along[i].total_cmp(&along[j]));
    let pairs = order
        .windows(2)
        .map(|w| (w[0], w[1]))
        .filter(|&(i, j)| along[j] > along[i]);
    match at {
        Some(f) => pairs
            .into_iter()
            .find(|&(i, j)| along[i] <= f && f <= along[j])
            .map(|(i, j)| (i, j, f)),
        None => pairs
            .map(|(i, j)| (i, j, 0.5 * (along[i] + along[j])))
            .fold(None, |best: Option<(usize, usize, f32)>, p| match best {
                Some(b) if (b.2 - 0.5).abs() <= (p.2 - 0.5).abs() => Some(b),
                _ => Some(p),
            }),
    }
}

fn paper(q: f32) -> Option<f64> {
    crate::eval::experiments::common::table::for_quality(&PAPER, q, |p| p.0).map(|p| p.1)
}

/// Writes table.md, qualities.csv, the plot and the image strips.
pub fn write(dir: &Path, r: &ViewsResults) -> Result<()> {
    let md = markdown(r)?;
    let path = dir.join("table.md");
    std::fs::write(&path, md).with_context(|| format!("writing {}", path.display()))?;
    qualities_csv(r)?.write_csv(dir.join("qualities.csv"))?;
    plots(dir, r)?;
    let size = r.args.common.size;
    for q in &r.qualities {
        let reference = &q.reference.radiance;
        let mut images: Vec<&[Vec3]> = vec![reference];
        images.extend(q.synthesized.iter().map(|f| f.image.as_slice()));
        images.extend(
            q.resampled
                .iter()
                .filter(|f| f.fill == Fill::Both)
                .map(|f| f.image.as_slice()),
        );
        images.push(&q.direct.image);
        write_strip(
            dir.join(format!("strip-q{}.png", q.quality)),
            size,
            &images,
            exposure_for(reference),
        )?;
    }
    Ok(())
}

fn bake_cells(b: &BakeCost) -> [String; 3] {
    let t = b.timing.as_ref();
    [
        cell(t.and_then(|t| t.radiosity_s), 3),
        cell(t.and_then(BakeTiming::per_image_s), 3),
        cell(t.and_then(BakeTiming::total_s), 3),
    ]
}

fn markdown(r: &ViewsResults) -> Result<String> {
    let c = &r.args.common;
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# View reconstruction: {} (paper Table 3)\n",
        c.scene.display()
    );
    let _ = writeln!(
        md,
        "1D view subspace from {} to {} ({:.3} scene units), t = {} s. Target views take camera `{}`'s \
         direction and field of view, {}x{} pixels.\n",
        r.segment.0,
        r.segment.1,
        r.segment.0.distance(r.segment.1),
        r.time,
        r.args.camera,
        c.size.0,
        c.size.1
    );
    md.push_str(&differences(
        c,
        r.base_size,
        "synthesis by this project's reprojection (pinterp's z-buffer, tolerance and fills), \
         samples averaged by ray angle, from the two bases flanking the target (the paper: pinterp, \
         180° bases)",
    ));
    md.push_str(&notes_md(&r.notes));

    md.push_str("## Scene decomposition\n\n");
    let mut t = Table::new([
        "quality",
        "views",
        "id-images",
        "planning (s)",
        "paper views",
        "paper time (s)",
    ]);
    let paper_plan = [(0.3, 2, 10.77), (0.6, 3, 34.12), (0.9, 5, 116.05)];
    for q in &r.qualities {
        let p =
            crate::eval::experiments::common::table::for_quality(&paper_plan, q.quality, |p| p.0);
        t.push([
            q.quality.to_string(),
            q.plan.views.len().to_string(),
            q.plan
                .steps
                .iter()
                .map(|s| s.id_images)
                .sum::<usize>()
                .to_string(),
            sig(q.plan_s, 3),
            p.map_or("—".into(), |p| p.1.to_string()),
            p.map_or("—".into(), |p| p.2.to_string()),
        ])?;
    }
    md.push_str(&t.to_markdown());

    md.push_str("\n## Base view synthesis\n\n");
    let mut t = Table::new([
        "image",
        "position",
        "along the segment",
        "radiosity (s)",
        "per image (s)",
        "bake in all (s)",
    ]);
    for q in &r.qualities {
        let [rad, per, all] = bake_cells(&q.resampled_bake);
        t.push([
            format!("sphere at the target, q = {}", q.quality),
            format!("{}", q.target),
            sig(q.target_along as f64, 4),
            rad,
            per,
            all,
        ])?;
        let [rad, per, all] = bake_cells(&q.bake);
        t.push([
            format!("bases 1 and 2, q = {}", q.quality),
            q.pair
                .iter()
                .map(|&v| q.plan.views[v].position.to_string())
                .collect::<Vec<_>>()
                .join("; "),
            q.pair
                .iter()
                .map(|&v| sig(q.along[v] as f64, 4))
                .collect::<Vec<_>>()
                .join("; "),
            rad,
            per,
            all,
        ])?;
    }
    md.push_str(&t.to_markdown());
    md.push_str(
        "\nPer image: a bake's rendering time over its images (the two bases are one bake). \
         In all: radiosity and every image. The paper: 570-729 minutes per base image.\n",
    );

    md.push_str("\n## Synthesis\n\n");
    let mut t = Table::new([
        "image",
        "fill",
        "base spacing",
        "time (s)",
        "loading (s)",
        "holes",
        "filled",
        "LRMS",
        "bias",
        "LRMS, emitters excluded",
        "block LRMS",
        "block p99",
        "FLIP",
        "paper LRMS",
    ]);
    for q in &r.qualities {
        let ref_s = q.reference.seconds;
        t.push([
            format!("path tracer reference, q = {} target", q.quality),
            "—".into(),
            "—".into(),
            ref_s.map_or("unknown (cached)".into(), |s| sig(s, 3)),
            "—".into(),
            "—".into(),
            "—".into(),
            "0".into(),
            "0".into(),
            "0".into(),
            "0".into(),
            "0".into(),
            "0".into(),
            "0.000".into(),
        ])?;
        let rows = q
            .synthesized
            .iter()
            .map(|f| (format!("q = {}", q.quality), f, q.spacing()))
            .chain(
                q.resampled
                    .iter()
                    .map(|f| (format!("resampled radiance, q = {}", q.quality), f, 0.0)),
            );
        for (name, f, spacing) in rows {
            let resampled = spacing == 0.0;
            let paper = if resampled {
                Some(PAPER_RESAMPLED)
            } else {
                paper(q.quality)
            };
            let fr = &f.frame;
            t.push([
                name,
                <&str>::from(f.fill).to_string(),
                sig(spacing as f64, 3),
                sig(fr.synth_s, 3),
                sig(fr.load_s, 3),
                fr.holes.to_string(),
                fr.filled.to_string(),
                sig(fr.error.lrms, 3),
                format!("{:+.4}", fr.error.bias),
                cell(fr.without_emitters.map(|e| e.lrms), 3),
                sig(fr.error.block_lrms, 3),
                sig(fr.error.block_p99, 3),
                cell(fr.flip, 3),
                // The paper's figures are for pinterp's default fills
                // (foreground and background).
                if f.fill == Fill::Both {
                    paper.map_or("—".into(), |p| format!("{p:.3}"))
                } else {
                    "—".into()
                },
            ])?;
        }
        let d = &q.direct;
        t.push([
            format!(
                "multipass render at the target, {} spp, q = {}",
                c.base_spp, q.quality
            ),
            "—".into(),
            "0".into(),
            sig(d.seconds, 3),
            "—".into(),
            "0".into(),
            "0".into(),
            sig(d.error.lrms, 3),
            format!("{:+.4}", d.error.bias),
            cell(d.without_emitters.map(|e| e.lrms), 3),
            sig(d.error.block_lrms, 3),
            sig(d.error.block_p99, 3),
            cell(d.flip, 3),
            "—".into(),
        ])?;
    }
    md.push_str(&t.to_markdown());
    md.push_str(
        "\nMultipass render at the target: the target view rendered directly by the renderer that \
         bakes the bases, at their samples per pixel and with their radiosity: the error of the bases \
         themselves, which no resampling can remove.\n",
    );
    md.push_str(
        "\nThe paper's figures (0.638 / 0.625 / 0.117, resampled 0.120) are against Radiance HQ \
         (45.7 minutes for the reference, 0.035-0.061 minutes per synthesis) and are listed beside \
         the foreground-and-background fill. Time: path tracing for the reference, synthesis \
         (base loading excluded) or rendering for the others. `strip-q<q>.png`: reference, fills \
         none / foreground / background / both, resampled radiance (both), multipass render at the \
         target, at one exposure.\n",
    );
    Ok(md)
}

fn qualities_csv(r: &ViewsResults) -> Result<Table> {
    let mut t = Table::new([
        "quality",
        "source",
        "fill",
        "views",
        "planning_s",
        "target_x",
        "target_y",
        "target_z",
        "spacing",
        "radiosity_s",
        "render_per_image_s",
        "seconds",
        "load_s",
        "holes",
        "filled",
        "lrms",
        "bias",
        "lrms_without_emitters",
        "block_lrms",
        "block_p99",
        "flip",
        "reference_s",
    ]);
    for q in &r.qualities {
        // (source, fill, spacing, bake, frame)
        let mut rows: Vec<(&str, &str, f32, &BakeCost, SynthFrame)> = Vec::new();
        for (source, runs, bake, spacing) in [
            ("pair", &q.synthesized, &q.bake, q.spacing()),
            ("resampled", &q.resampled, &q.resampled_bake, 0.0),
        ] {
            rows.extend(
                runs.iter()
                    .map(|f| (source, <&str>::from(f.fill), spacing, bake, f.frame.clone())),
            );
        }
        let d = &q.direct;
        let direct = SynthFrame {
            frame: 0,
            time: r.time,
            synth_s: d.seconds,
            load_s: 0.0,
            images: 0,
            holes: 0,
            filled: 0,
            error: d.error,
            without_emitters: d.without_emitters,
            flip: d.flip,
        };
        rows.push(("multipass", "", 0.0, &q.resampled_bake, direct));
        for (source, fill, spacing, bake, fr) in rows {
            let timing = bake.timing.as_ref();
            t.push([
                q.quality.to_string(),
                source.to_string(),
                fill.to_string(),
                q.plan.views.len().to_string(),
                q.plan_s.to_string(),
                q.target.x.to_string(),
                q.target.y.to_string(),
                q.target.z.to_string(),
                spacing.to_string(),
                timing
                    .and_then(|t| t.radiosity_s)
                    .map_or(String::new(), |x| x.to_string()),
                timing
                    .and_then(BakeTiming::per_image_s)
                    .map_or(String::new(), |x| x.to_string()),
                fr.synth_s.to_string(),
                fr.load_s.to_string(),
                fr.holes.to_string(),
                fr.filled.to_string(),
                fr.error.lrms.to_string(),
                fr.error.bias.to_string(),
                fr.without_emitters
                    .map_or(String::new(), |e| e.lrms.to_string()),
                fr.error.block_lrms.to_string(),
                fr.error.block_p99.to_string(),
                fr.flip.map_or(String::new(), |x| x.to_string()),
                q.reference.seconds.map_or(String::new(), |x| x.to_string()),
            ])?;
        }
    }
    Ok(t)
}

/// LRMS against what each image cost (planning, bake and synthesis), one
/// line per fill mode through the qualities, and against base spacing.
fn plots(dir: &Path, r: &ViewsResults) -> Result<()> {
    let cost = |q: &ViewsQuality, f: &FillRun| {
        q.plan_s
            + q.bake
                .timing
                .as_ref()
                .and_then(BakeTiming::total_s)
                .unwrap_or(f64::NAN)
            + f.frame.seconds()
    };
    let mut series: Vec<Series> = FILLS
        .iter()
        .enumerate()
        .map(|(k, &fill)| Series {
            label: format!("fill {}", <&str>::from(fill)),
            points: r
                .qualities
                .iter()
                .map(|q| {
                    (
                        cost(q, &q.synthesized[k]),
                        q.synthesized[k].frame.error.lrms,
                    )
                })
                .collect(),
        })
        .collect();
    series.push(Series {
        label: "resampled radiance (fill both)".into(),
        points: r
            .qualities
            .iter()
            .filter_map(|q| {
                let f = q.resampled.iter().find(|f| f.fill == Fill::Both)?;
                let bake = q.resampled_bake.timing.as_ref()?.total_s()?;
                Some((bake + f.frame.seconds(), f.frame.error.lrms))
            })
            .collect(),
    });
    plot::write_png(
        dir.join("error_vs_time.png"),
        &Plot {
            title: "Target view: error against cost",
            x_label: "seconds (planning, bake, synthesis)",
            y_label: "LRMS",
            scale: Scale::LogLog,
            series: &series,
        },
    )?;
    let series: Vec<Series> = FILLS
        .iter()
        .enumerate()
        .map(|(k, &fill)| Series {
            label: format!("fill {}", <&str>::from(fill)),
            points: r
                .qualities
                .iter()
                .map(|q| (q.spacing() as f64, q.synthesized[k].frame.error.lrms))
                .collect(),
        })
        .collect();
    plot::write_png(
        dir.join("error_vs_spacing.png"),
        &Plot {
            title: "Target view midway between two bases: error against their distance",
            x_label: "distance between the bases (scene units)",
            y_label: "LRMS",
            scale: Scale::Linear,
            series: &series,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_target_lies_midway_between_the_pair_nearest_the_middle() {
        // Two bases at the ends: the middle.
        assert_eq!(flanking(&[0.0, 1.0], None), Some((0, 1, 0.5)));
        // Plan order is not segment order; the middle is a base, so the
        // first of the two pairs beside it.
        let along = [0.0, 1.0, 0.5, 0.25, 0.75];
        assert_eq!(flanking(&along, None), Some((3, 2, 0.375)));
        // A fixed target: the pair around it.
        assert_eq!(flanking(&along, Some(0.6)), Some((2, 4, 0.6)));
        assert_eq!(flanking(&along, Some(0.0)), Some((0, 3, 0.0)));
        // One base has no pair.
        assert_eq!(flanking(&[0.5], None), None);
        assert_eq!(flanking(&[0.0, 1.0], Some(1.5)), None);
        // Two bases at one place are no pair.
        assert_eq!(flanking(&[0.2, 0.2], None), None);
    }

    #[test]
    fn the_subspace_runs_along_the_longest_side_through_the_middle() {
        let rect = ViewSpace::Rectangle {
            min: Vec3::new(2.0, 1.6, 1.8),
            max: Vec3::new(6.0, 1.6, 4.5),
        };
        assert_eq!(
            default_segment(&rect),
            (Vec3::new(2.0, 1.6, 3.15), Vec3::new(6.0, 1.6, 3.15))
        );
        let seg = ViewSpace::Segment {
            a: Vec3::ZERO,
            b: Vec3::X,
        };
        assert_eq!(default_segment(&seg), (Vec3::ZERO, Vec3::X));
        let s = (Vec3::new(2.0, 0.0, 0.0), Vec3::new(6.0, 0.0, 0.0));
        assert_eq!(along_segment(s, Vec3::new(3.0, 5.0, 0.0)), 0.25);
    }
}
