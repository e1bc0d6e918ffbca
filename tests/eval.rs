//! Reports of the experiments as a reader meets them: files that open,
//! tables that parse back, figures that match what was measured.

use std::io::BufReader;
use std::path::{Path, PathBuf};

use glam::Vec3;
use rangewalk::accel::Backend;
use rangewalk::eval::experiments::common::convergence::ConvergencePoint;
use rangewalk::eval::experiments::common::plot::{self, Plot, Scale, Series};
use rangewalk::eval::experiments::common::table::Table;
use rangewalk::eval::experiments::indirect::{
    run_indirect, FrameResult, IndirectArgs, IndirectResults, PathTracerRun, QualityRun,
};
use rangewalk::eval::metrics::ImageError;
use rangewalk::eval::reference::Reference;
use rangewalk::quality::Quality;
use rangewalk::radiosity::{SimplifyStats, SolveStats};

/// Width, height and RGB bytes of a PNG file (decoded with the `png` crate,
/// independent of how it was written).
fn decode_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut reader = png::Decoder::new(BufReader::new(file)).read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb, "{}", path.display());
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

/// RFC 4180 records (quoted fields with doubled quotes), one per line.
fn parse_csv(text: &str) -> Vec<Vec<String>> {
    let mut rows = Vec::new();
    let (mut row, mut field, mut quoted) = (Vec::new(), String::new(), false);
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                chars.next();
                field.push('"');
            }
            ('"', _) => quoted = !quoted,
            (',', false) => row.push(std::mem::take(&mut field)),
            ('\n', false) => {
                row.push(std::mem::take(&mut field));
                rows.push(std::mem::take(&mut row));
            }
            (c, _) => field.push(c),
        }
    }
    rows
}

fn read_csv(path: &Path) -> Vec<Vec<String>> {
    parse_csv(&std::fs::read_to_string(path).unwrap())
}

/// Pixels that are neither white nor grey: drawn in a series colour.
fn coloured_pixels(rgb: &[u8]) -> usize {
    rgb.chunks(3)
        .filter(|p| p.iter().max().unwrap() - p.iter().min().unwrap() > 40)
        .count()
}

#[test]
fn plots_are_png_images_with_their_series() {
    let dir = tempfile::tempdir().unwrap();
    let series = [
        Series {
            label: "path tracer".into(),
            points: vec![(0.1, 0.9), (0.2, 0.6), (0.4, 0.45), (0.8, 0.3)],
        },
        Series {
            // Zero and negative values have no place on log axes.
            label: "q = 0.3".into(),
            points: vec![(0.5, 0.2), (0.0, 0.1), (1.0, -1.0)],
        },
    ];
    for (name, scale) in [("lin.png", Scale::Linear), ("log.png", Scale::LogLog)] {
        let path = dir.path().join(name);
        plot::write_png(
            &path,
            &Plot {
                title: "Error",
                x_label: "seconds",
                y_label: "LRMS",
                scale,
                series: &series,
            },
        )
        .unwrap();
        assert!(std::fs::metadata(&path).unwrap().len() > 1000);
        let (w, h, rgb) = decode_png(&path);
        assert_eq!((w, h), (900, 600));
        assert!(coloured_pixels(&rgb) > 200, "{name}: series not drawn");
    }
    // Nothing to draw still makes a valid (empty) chart.
    let path = dir.path().join("empty.png");
    plot::write_png(
        &path,
        &Plot {
            title: "Nothing",
            x_label: "x",
            y_label: "y",
            scale: Scale::LogLog,
            series: &[],
        },
    )
    .unwrap();
    let (_, _, rgb) = decode_png(&path);
    assert_eq!(coloured_pixels(&rgb), 0);
}

#[test]
fn csv_parses_back_to_the_table() {
    let mut t = Table::new(["method", "quality", "note"]);
    t.push(["multipass", "0.3", "plain"]).unwrap();
    t.push(["path-tracer", "0.3;0.6", "a, b and \"c\""])
        .unwrap();
    t.push(["x", "", "line\nbreak"]).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.csv");
    t.write_csv(&path).unwrap();
    let rows = read_csv(&path);
    assert_eq!(rows[0], t.headers);
    assert_eq!(&rows[1..], &t.rows[..]);
}

fn frame(frame: usize, time: f32, lrms: f64, bias: f64, render_s: f64) -> FrameResult {
    FrameResult {
        frame,
        time,
        interpolation_s: 0.01,
        render_s,
        error: ImageError {
            lrms,
            bias,
            block_lrms: lrms / 4.0,
            block_p99: lrms * 2.0,
            pixels: 16,
        },
        flip: Some(lrms / 2.0),
    }
}

/// Results of two qualities over three frames, written by hand.
fn results(out: PathBuf) -> IndirectResults {
    let args = IndirectArgs {
        scene: "scenes/cornell-box/scene.toml".into(),
        quality: [0.3, 0.5].map(|q| Quality::new(q).unwrap()).to_vec(),
        out: out.clone(),
        frames: Some(3),
        size: (4, 4),
        camera: "main".into(),
        reference_spp: 64,
        spp: 4,
        backend: Backend::Bvh,
        no_flip: false,
    };
    let times = vec![0.0, 0.5, 1.0];
    let quality = |q: f32, lrms: [f64; 3], solves: usize| QualityRun {
        quality: q,
        simplify: SimplifyStats {
            initial_surfaces: 36,
            pruned_surfaces: 6,
            final_surfaces: 30,
            visibility_rays: 1000,
            seconds: 0.5,
        },
        simplify_s: 0.5,
        decompose_s: 2.0,
        records: 60,
        solves: (0..solves)
            .map(|i| {
                let stats = SolveStats {
                    iterations: 10,
                    residual: 1e-4,
                    seconds: 0.5,
                    ..SolveStats::default()
                };
                (i as f32 / (solves - 1) as f32, stats)
            })
            .collect(),
        frames: (0..3)
            .map(|i| frame(i, times[i], lrms[i], 0.01, 1.0))
            .collect(),
        preview: vec![Vec3::splat(0.5); 16],
    };
    IndirectResults {
        args,
        times: times.clone(),
        preview_frame: 1,
        references: (0..3)
            .map(|_| Reference {
                radiance: vec![Vec3::splat(0.4); 16],
                seconds: Some(10.0),
                reused: false,
            })
            .collect(),
        qualities: vec![
            quality(0.3, [0.2, 0.1, 0.15], 2),
            quality(0.5, [0.1, 0.05, 0.12], 3),
        ],
        convergence: [1, 2, 4]
            .map(|spp| ConvergencePoint {
                spp,
                seconds: 0.1 * spp as f64,
                error: ImageError {
                    lrms: 1.0 / (spp as f64).sqrt(),
                    bias: 0.0,
                    block_lrms: 0.5 / (spp as f64).sqrt(),
                    block_p99: 2.0 / (spp as f64).sqrt(),
                    pixels: 16,
                },
                flip: Some(0.3 / (spp as f64).sqrt()),
            })
            .to_vec(),
        equal_time: vec![PathTracerRun {
            spp: 4,
            matches: vec![0.3, 0.5],
            capped: true,
            frames: (0..3).map(|i| frame(i, times[i], 0.5, 0.0, 0.4)).collect(),
            preview: vec![Vec3::splat(0.3); 16],
        }],
        notes: vec!["no glossy or mirror surfaces: no specular rays are traced".into()],
        out,
    }
}

#[test]
fn report_files_hold_the_measurements() {
    let dir = tempfile::tempdir().unwrap();
    let r = results(dir.path().to_path_buf());
    rangewalk::eval::experiments::indirect::report::write(dir.path(), &r).unwrap();

    let md = std::fs::read_to_string(dir.path().join("table.md")).unwrap();
    // Totals: 0.5 simplify + 2 decompose + 3 x (0.01 + 1) per frame.
    assert!(md.contains("| 5.53 |"), "{md}");
    // Quality 0.3: mean LRMS 0.15 beside the paper's 0.147 (Table 2) and
    // 0.381 (Table 1); 0.5 has no paper figure.
    assert!(md.contains("| 0.150 | 0.200 |"), "{md}");
    // Beside them: mean bias, mean block LRMS (a quarter of LRMS here),
    // mean block p99 (twice it), mean and max FLIP.
    assert!(
        md.contains("| 0.150 | 0.200 | +0.0100 | 0.0375 | 0.300 | 0.0750 | 0.100 |"),
        "{md}"
    );
    assert!(md.contains("0.147") && md.contains("0.381"), "{md}");
    // Scene decomposition: simplify 0.5 + (2 - 2 x 0.5) of bisection.
    assert!(md.contains("| 1.50 | 1.00 |"), "{md}");
    assert!(md.contains("no specular rays"), "{md}");
    assert!(
        md.contains("path tracer 4 spp (time of q = 0.3, 0.5; capped)"),
        "{md}"
    );

    let rows = read_csv(&dir.path().join("frames.csv"));
    assert_eq!(
        rows.len(),
        1 + 3 * 3,
        "header + 3 frames x (2 qualities + 1 path tracer)"
    );
    let col = |name: &str| rows[0].iter().position(|h| h == name).unwrap();
    let (method, quality, lrms, flip) = (col("method"), col("quality"), col("lrms"), col("flip"));
    let q03: Vec<f64> = rows[1..]
        .iter()
        .filter(|r| r[method] == "multipass" && r[quality] == "0.3")
        .map(|r| r[lrms].parse().unwrap())
        .collect();
    assert_eq!(q03, [0.2, 0.1, 0.15]);
    assert!(rows[1..]
        .iter()
        .any(|r| r[method] == "path-tracer" && r[quality] == "0.3;0.5"));
    assert_eq!(rows[1][flip].parse::<f64>().unwrap(), 0.1);
    let (block, p99) = (col("block_lrms"), col("block_p99"));
    assert_eq!(rows[1][block].parse::<f64>().unwrap(), 0.05);
    assert_eq!(rows[1][p99].parse::<f64>().unwrap(), 0.4);

    let conv = read_csv(&dir.path().join("convergence.csv"));
    assert_eq!(conv.len(), 4);
    assert_eq!(conv[3][0], "4");
    let flip_at = conv[0].iter().position(|h| h == "flip").unwrap();
    assert_eq!(conv[3][flip_at], "0.1500");

    for name in [
        "error_per_frame.png",
        "error_vs_time.png",
        "preview-reference.png",
        "preview-q0.3.png",
        "preview-q0.5.png",
        "preview-path-tracer-4spp.png",
    ] {
        let (w, h, rgb) = decode_png(&dir.path().join(name));
        assert!(
            w > 0 && h > 0 && rgb.len() == (w * h * 3) as usize,
            "{name}"
        );
    }
    // Previews share one exposure: the reference's mean at middle grey.
    let (_, _, reference) = decode_png(&dir.path().join("preview-reference.png"));
    let (_, _, pt) = decode_png(&dir.path().join("preview-path-tracer-4spp.png"));
    assert!(reference[0] > pt[0], "the darker image stays darker");
    // 0.18 in sRGB is about 118.
    assert!((reference[0] as i32 - 118).abs() <= 1, "{}", reference[0]);
}

fn experiment(args: &[&str], python: &str) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_rangewalk"))
        .arg("experiment")
        .args(args)
        .env("RANGEWALK_PYTHON", python)
        .output()
        .unwrap()
}

#[test]
fn command_line_errors_name_the_fault_and_write_nothing() {
    let root = tempfile::tempdir().unwrap();
    let out = root.path().join("x");
    let out_s = out.to_str().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-box/scene.toml");
    let cases: [(&[&str], &str); 4] = [
        (
            &["indirect", scene, "--quality", "0.3,1.5", "--out", out_s],
            "quality 1.5",
        ),
        (&["indirect", scene, "--size", "0x8", "--out", out_s], "0x8"),
        (
            &["indirect", scene, "--camera", "nope", "--out", out_s],
            "nope",
        ),
        // FLIP missing: the fix is named, and how to do without it.
        (&["indirect", scene, "--out", out_s], "make deps"),
    ];
    for (args, expected) in cases {
        let o = experiment(args, "/nonexistent/python");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?}");
        assert!(err.contains(expected), "{args:?}: {err}");
        assert!(!out.exists() && !root.path().join("x.partial").exists());
    }
    let o = experiment(&["indirect", scene, "--out", out_s], "/nonexistent/python");
    assert!(String::from_utf8_lossy(&o.stderr).contains("--no-flip"));
}

/// The whole experiment on a tiny configuration: needs the radiosity stages
/// and the multipass renderer.
mod end_to_end {
    use super::*;
    use rangewalk::eval::flip::Flip;

    fn scene(name: &str) -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name)
            .join("scene.toml")
    }

    fn args(scene: PathBuf, out: PathBuf, quality: Vec<f32>) -> IndirectArgs {
        // `make deps` installs FLIP: without it the test fails, it does not
        // quietly leave FLIP out.
        if let Err(e) = Flip::locate() {
            panic!("FLIP is required by the end-to-end test: {e:#}");
        }
        IndirectArgs {
            scene,
            quality: quality
                .into_iter()
                .map(|q| Quality::new(q).unwrap())
                .collect(),
            out,
            frames: Some(3),
            size: (32, 32),
            camera: "main".into(),
            reference_spp: 64,
            spp: 4,
            backend: Backend::default_available(),
            no_flip: false,
        }
    }

    fn mean_lrms(frames: &[FrameResult]) -> f64 {
        frames.iter().map(|f| f.error.lrms).sum::<f64>() / frames.len() as f64
    }

    #[test]
    fn animated_cornell_box() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("indirect");
        let a = args(scene("cornell-box"), out.clone(), vec![0.3, 0.9]);
        let r = run_indirect(&a).unwrap();
        assert_eq!(r.out, out);
        assert!(!root.path().join("indirect.partial").exists());
        assert_eq!(r.times, [0.0, 0.5, 1.0]);
        assert!(r.references.iter().all(|x| !x.reused));

        // Path tracing the Cornell box is noisy (a small bright light, much
        // of the image lit indirectly): at 32x32 even the 64-spp reference
        // has a relative LRMS of about 0.3. The multipass image traces
        // direct light only, so its noise must stay below one-sample path
        // tracing.
        let pt1 = r.convergence[0].error.lrms;
        for q in &r.qualities {
            assert_eq!(q.frames.len(), 3);
            // The boxes move: the decomposition solves at both ends at least.
            assert!(q.solves.len() >= 2, "q = {}: {:?}", q.quality, q.solves);
            assert!(q.simplify.final_surfaces > 0);
            for f in &q.frames {
                assert!(f.error.lrms < pt1, "{f:?} against {pt1} at 1 spp");
                // Indirect light is a large part of the Cornell box: a
                // renderer that lost it is 23% too dark.
                assert!(f.error.bias.abs() < 0.12, "q = {}: {f:?}", q.quality);
                assert_eq!(f.flip.is_some(), !a.no_flip);
                assert!(f.error.block_lrms <= f.error.lrms, "{f:?}");
            }
        }

        // The path tracer converges: 16 times the samples, a quarter of the
        // noise (within Monte Carlo slack and the reference's own noise).
        let c = &r.convergence;
        assert_eq!(c[0].spp, 1);
        assert!(c.windows(2).all(|w| w[1].spp == 2 * w[0].spp));
        if let Some(p16) = c.iter().find(|p| p.spp == 16) {
            assert!(p16.error.lrms < 0.5 * c[0].error.lrms, "{c:?}");
        }
        // Every point of the curve has its FLIP, for the comparison at
        // equal FLIP.
        assert!(c.iter().all(|p| p.flip.is_some_and(|f| f > 0.0)), "{c:?}");
        assert!(!r.equal_time.is_empty());
        for p in &r.equal_time {
            assert!(mean_lrms(&p.frames).is_finite());
        }

        let md = std::fs::read_to_string(out.join("table.md")).unwrap();
        assert!(md.contains("q = 0.3") && md.contains("q = 0.9"));
        let rows = read_csv(&out.join("frames.csv"));
        assert_eq!(rows.len(), 1 + 3 * (2 + r.equal_time.len()));
        for name in [
            "error_per_frame.png",
            "error_vs_time.png",
            "preview-q0.9.png",
        ] {
            decode_png(&out.join(name));
        }

        // A rerun reuses the references and replaces the report.
        let again = run_indirect(&args(scene("cornell-box"), out.clone(), vec![0.6])).unwrap();
        assert!(again.references.iter().all(|x| x.reused));
        for (a, b) in r.references.iter().zip(&again.references) {
            assert_eq!(a.radiance, b.radiance);
        }
        let md = std::fs::read_to_string(out.join("table.md")).unwrap();
        assert!(md.contains("q = 0.6") && !md.contains("q = 0.3"), "{md}");
        assert!(md.contains("3 of 3 references reused"), "{md}");
    }

    #[test]
    fn static_furnace_skips_the_temporal_stage() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("furnace");
        let mut a = args(scene("furnace"), out.clone(), vec![0.5]);
        a.frames = None;
        a.size = (16, 16);
        let r = run_indirect(&a).unwrap();
        assert_eq!(r.times.len(), 1);
        let q = &r.qualities[0];
        assert_eq!(q.solves.len(), 1);
        // Radiance E / (1 - rho) = 2 everywhere: the multipass image's
        // mean matches the converged reference's.
        assert!(q.frames[0].error.bias.abs() < 0.1, "{:?}", q.frames[0]);
        let md = std::fs::read_to_string(out.join("table.md")).unwrap();
        assert!(md.contains("static scene"), "{md}");
    }
}
