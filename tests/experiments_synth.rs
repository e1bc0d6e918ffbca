//! The synthesis experiments end to end on a tiny configuration: the
//! motion experiment (paper Table 4) on the animated Cornell box, its
//! report files, and a rerun that reuses the bakes it left.

use std::path::{Path, PathBuf};

use rangewalk::accel::Backend;
use rangewalk::bake::IndirectSource;
use rangewalk::eval::experiments::common::setup::{CommonArgs, SequenceArgs};
use rangewalk::eval::experiments::motion::{self, MotionArgs};
use rangewalk::plan::ViewFitness;
use rangewalk::quality::Quality;
use rangewalk::synth::{Blend, Fill, TimeInterp};

fn args(out: PathBuf) -> MotionArgs {
    MotionArgs {
        common: CommonArgs {
            scene: PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml"),
            quality: [0.3, 0.9].map(|q| Quality::new(q).unwrap()).to_vec(),
            out,
            size: (32, 32),
            reference_spp: 64,
            base_spp: 2,
            base_size: Some(64),
            supersample: 2,
            blend: Blend::Average,
            backend: Backend::default_available(),
            view_fitness: ViewFitness::Ids,
            indirect: IndirectSource::Radiosity,
            no_flip: true,
        },
        camera: "main".into(),
        sequence: SequenceArgs {
            frames: Some(3),
            time_interp: vec![TimeInterp::Linear, TimeInterp::Motion, TimeInterp::Reshade],
            fill: Fill::Both,
        },
    }
}

/// Data rows of a CSV file (no quoted fields in these).
fn csv_rows(path: &Path) -> Vec<Vec<String>> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(String::from).collect())
        .collect()
}

#[test]
fn motion_on_the_cornell_box() {
    let root = tempfile::tempdir().unwrap();
    let out = root.path().join("motion");
    let r = motion::run(&args(out.clone())).unwrap();
    assert_eq!(r.out, out);
    assert!(!root.path().join("motion.partial").exists());
    assert_eq!(r.times, [0.0, 0.5, 1.0]);

    for name in [
        "table.md",
        "qualities.csv",
        "frames.csv",
        "error_per_frame.png",
        "error_vs_time.png",
        "strip-q0.3.png",
        "strip-q0.9.png",
    ] {
        let p = out.join(name);
        assert!(
            std::fs::metadata(&p).is_ok_and(|m| m.len() > 0),
            "{} missing",
            p.display()
        );
    }
    assert!(out.join("bakes/q0.3/manifest.json").exists());
    assert!(out.join("bakes/q0.9/manifest.json").exists());

    let md = std::fs::read_to_string(out.join("table.md")).unwrap();
    for q in ["0.3", "0.9"] {
        for mode in ["linear", "motion", "reshade"] {
            let row = format!("| q = {q}, {mode} |");
            assert_eq!(md.matches(&row).count(), 1, "{row} in\n{md}");
        }
    }
    assert!(md.contains("fully rendered"), "{md}");
    assert!(md.contains("blended by averaging"), "{md}");
    assert_eq!(csv_rows(&out.join("qualities.csv")).len(), 2 * 3);
    assert_eq!(csv_rows(&out.join("frames.csv")).len(), 2 * 3 * 3);

    for q in &r.qualities {
        // One view at the camera; the boxes move, so two times at least.
        assert_eq!(q.plan.views.len(), 1);
        assert!(q.baked_images >= 2, "q = {}: {:?}", q.quality, q.plan.views);
        assert!(q.bake.timing.is_some() && !q.bake.reused);
        assert_eq!(q.modes.len(), 3);
        for m in &q.modes {
            assert_eq!(m.frames.len(), 3);
            for f in &m.frames {
                assert!(
                    f.error.lrms.is_finite() && f.error.bias.is_finite(),
                    "q = {}, {:?}: {f:?}",
                    q.quality,
                    m.mode
                );
                assert!(f.synth_s >= 0.0 && f.load_s >= 0.0);
                assert!(f.flip.is_none());
            }
        }
    }

    // A rerun reuses the bakes and references, and still reports the bake
    // times the first run recorded; its frames are blended as it asks.
    let mut nearest = args(out.clone());
    nearest.common.blend = Blend::Nearest;
    let again = motion::run(&nearest).unwrap();
    let md = std::fs::read_to_string(out.join("table.md")).unwrap();
    assert!(md.contains("blended nearest first"), "{md}");
    assert!(again.references.iter().all(|x| x.reused));
    for (a, b) in r.qualities.iter().zip(&again.qualities) {
        assert!(b.bake.reused);
        assert_eq!(a.bake.timing, b.bake.timing);
        assert_eq!(a.plan.views, b.plan.views);
    }
}
