//! Temporal decomposition driven by synthetic solutions whose change in
//! time is known, so that where the bisection must (and must not) split is
//! known too; and interpolation in time.

use std::path::PathBuf;

use anyhow::Result;
use glam::Vec3;
use rangewalk::accel::{self, Backend, RayEngine};
use rangewalk::quality::Quality;
use rangewalk::radiosity::temporal::{compare, decompose_with, Thresholds, TimeSeries};
use rangewalk::radiosity::{IndirectSolution, Simplified, SolveStats};
use rangewalk::ray::Ray;
use rangewalk::scene::{Motion, Scene};

fn cornell() -> Scene {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml");
    Scene::load(&path).unwrap()
}

fn solution(time: f32, indirect: Vec<Vec3>) -> IndirectSolution {
    IndirectSolution {
        time,
        direct: vec![Vec3::ZERO; indirect.len()],
        indirect,
        stats: SolveStats::default(),
    }
}

/// Decomposes `scene` with irradiance `field(record, t)` standing in for
/// the solver.
fn run(scene: &Scene, q: f32, field: impl Fn(usize, f32) -> Vec3) -> TimeSeries {
    let simplified = Simplified::whole(scene);
    let mut engine = accel::build(Backend::Bvh, &scene.geometry(), &scene.at(0.0)).unwrap();
    let solve = |_: &Scene, s: &Simplified, _: &dyn RayEngine, t: f32, _: Quality| {
        Ok(solution(
            t,
            (0..s.records.len()).map(|i| field(i, t)).collect(),
        ))
    };
    decompose_with(
        scene,
        &simplified,
        engine.as_mut(),
        Quality::new(q).unwrap(),
        solve,
    )
    .unwrap()
}

#[test]
fn static_scene_gets_one_solution() {
    let mut scene = cornell();
    for o in &mut scene.objects {
        o.motion = Motion::default();
    }
    let series = run(&scene, 0.9, |i, t| Vec3::splat(i as f32 + t));
    assert_eq!(series.times, vec![scene.animation.start]);
    assert_eq!(series.stats.solves, 1);
    assert!(series.stats.static_scene && series.stats.intervals.is_empty());
    // Held at every time.
    assert_eq!(series.indirect_at(0.7), series.solutions[0].indirect);
}

#[test]
fn unchanging_light_needs_only_the_two_ends() {
    let scene = cornell();
    let series = run(&scene, 1.0, |i, _| Vec3::splat(1.0 + (i % 7) as f32));
    assert_eq!(series.times, vec![0.0, 1.0]);
    assert_eq!(series.stats.depth, 0);
    assert!(!series.stats.intervals[0].split);
}

/// Light that jumps at t = 0.3 on a third of the records: bisection
/// homes in on the jump and leaves the rest of the animation alone.
#[test]
fn bisection_refines_around_a_change_only() {
    let scene = cornell();
    let jump = 0.3;
    let field = move |i: usize, t: f32| {
        let base = Vec3::new(1.0, 0.8, 0.5);
        if i.is_multiple_of(3) && t > jump {
            base * 4.0
        } else {
            base
        }
    };
    let q = 0.9;
    let series = run(&scene, q, field);
    let limits = Thresholds::for_quality(Quality::new(q).unwrap());
    assert_eq!(series.stats.depth, limits.max_depth);
    assert_eq!(series.times.len(), series.stats.solves);
    assert!(series.times.windows(2).all(|w| w[0] < w[1]));
    // One split per level along the path to the jump: two ends plus one
    // midpoint per level.
    assert_eq!(series.stats.solves, 2 + limits.max_depth as usize);
    let width = 1.0 / (1u32 << limits.max_depth) as f32;
    let k = series.times.partition_point(|&t| t <= jump);
    assert!((series.times[k] - series.times[k - 1] - width).abs() < 1e-6);
    for test in &series.stats.intervals {
        let contains = test.t0 < jump && jump < test.t1;
        assert_eq!(
            test.split,
            contains && test.depth < limits.max_depth,
            "{test:?}"
        );
    }
}

#[test]
fn higher_quality_never_solves_fewer_times() {
    let scene = cornell();
    let field = |i: usize, t: f32| Vec3::splat(1.0 + (i % 5) as f32 * t * t);
    let mut last = 0;
    for q in [0.0, 0.3, 0.6, 0.9, 1.0] {
        let n = run(&scene, q, field).stats.solves;
        assert!(n >= last, "q = {q}: {n} solves after {last}");
        last = n;
    }
    assert!(last > 2);
}

#[test]
fn engine_is_posed_at_each_solve_time() {
    let scene = cornell();
    let simplified = Simplified::whole(&scene);
    // A face of the moving short box (object 6) whose normal has a
    // component along its motion.
    let patch = *simplified
        .patches
        .iter()
        .find(|p| p.object == 6 && p.normal().x.abs() > 0.5)
        .unwrap();
    let centre = (patch.vertices[0] + patch.vertices[1] + patch.vertices[2]) / 3.0;
    let mut engine = accel::build(Backend::Bvh, &scene.geometry(), &scene.at(0.5)).unwrap();
    let solve = |sc: &Scene, s: &Simplified, e: &dyn RayEngine, t: f32, _: Quality| -> Result<_> {
        let pose = sc.at(t)[6];
        let p = pose.transform_point3(centre);
        let n = pose.transform_vector3(patch.normal()).normalize();
        let hit = e.intersect(&Ray::new(p + n * 50.0, -n)).unwrap();
        assert_eq!(hit.object, 6);
        assert!((hit.t - 50.0).abs() < 1e-2, "t = {t}: hit at {}", hit.t);
        Ok(solution(
            t,
            vec![Vec3::splat(1.0 + 10.0 * t); s.records.len()],
        ))
    };
    let q = Quality::new(0.6).unwrap();
    let series = decompose_with(&scene, &simplified, engine.as_mut(), q, solve).unwrap();
    assert!(series.stats.solves > 2);
}

#[test]
fn interpolation_is_linear_between_and_held_outside() {
    let a = vec![Vec3::new(1.0, 2.0, 3.0), Vec3::ZERO];
    let b = vec![Vec3::new(3.0, 2.0, 1.0), Vec3::splat(8.0)];
    let c = vec![Vec3::splat(5.0), Vec3::splat(4.0)];
    let series = TimeSeries {
        times: vec![0.0, 1.0, 3.0],
        solutions: vec![
            solution(0.0, a.clone()),
            solution(1.0, b.clone()),
            solution(3.0, c.clone()),
        ],
        quality: Quality::DEFAULT,
        stats: Default::default(),
    };
    assert_eq!(series.indirect_at(-2.0), a);
    assert_eq!(series.indirect_at(f32::NAN), a);
    assert_eq!(series.indirect_at(0.0), a);
    assert_eq!(series.indirect_at(1.0), b);
    assert_eq!(series.indirect_at(3.0), c);
    assert_eq!(series.indirect_at(9.0), c);
    let m = series.indirect_at(0.25);
    assert!((m[0] - Vec3::new(1.5, 2.0, 2.5)).length() < 1e-6);
    assert!((m[1] - Vec3::splat(2.0)).length() < 1e-6);
    let m = series.indirect_at(2.0);
    assert!((m[1] - Vec3::splat(6.0)).length() < 1e-6);
}

#[test]
fn comparison_is_relative_and_safe_for_darkness() {
    let a = vec![Vec3::ONE; 4];
    let b = vec![Vec3::ONE, Vec3::ONE, Vec3::ONE, Vec3::splat(3.0)];
    let (rms, unchanged) = compare(&a, &b, 0.1);
    // Differences 0,0,0,2: RMS 1; mean of the averages 1.25.
    assert!((rms - 1.0 / 1.25).abs() < 1e-9, "{rms}");
    assert_eq!(unchanged, 0.75);
    // Scaling both changes nothing.
    let scale = |v: &[Vec3], s: f32| v.iter().map(|&x| x * s).collect::<Vec<_>>();
    for s in [1e-6, 1e8] {
        let (r, u) = compare(&scale(&a, s), &scale(&b, s), 0.1);
        assert!((r - rms).abs() < 1e-5 * rms && u == unchanged);
    }
    let zero = vec![Vec3::ZERO; 4];
    assert_eq!(compare(&zero, &zero, 0.1), (0.0, 1.0));
    assert_eq!(compare(&[], &[], 0.1), (0.0, 1.0));
}

/// The bake directory: exact round trips, atomic replacement, and errors
/// that name the file and field at fault.
mod bake {
    use super::*;
    use rangewalk::radiosity::store::{self, load, partial_path, save};
    use std::fs;
    use std::path::Path;

    fn baked(dir: &Path) -> (Simplified, TimeSeries) {
        let scene = cornell();
        let field = |i: usize, t: f32| {
            Vec3::new(0.1 + i as f32 * 1e-3, 1e-7 * t, 3e4 + t.sin()) * (1.0 + t)
        };
        let mut series = run(&scene, 0.5, field);
        series.solutions[0].direct[3] = Vec3::new(f32::MIN_POSITIVE, 1e30, 0.1);
        series.solutions[0].stats.residual = 1.234_567_890_123e-9;
        series.solutions[0].stats.shadow_rays = 1 << 40;
        let mut s = Simplified::whole(&scene);
        s.stats.seconds = 0.1 + 0.2;
        s.stats.visibility_rays = 12345;
        s.pruned = vec![(0, 1), (0, 7), (3, 0), (u32::MAX, u32::MAX)];
        save(dir, &scene, &s, &series).unwrap();
        (s, series)
    }

    #[test]
    fn round_trip_is_bit_identical() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("cb.bake");
        let (s, series) = baked(&dir);
        assert!(series.stats.solves > 2 && !series.stats.intervals.is_empty());
        let (s2, series2) = load(&dir).unwrap();
        assert_eq!(s2, s);
        assert_eq!(series2, series);
        let bits = |v: &[Vec3]| {
            v.iter()
                .flat_map(|x| x.to_array().map(f32::to_bits))
                .collect::<Vec<_>>()
        };
        for (a, b) in series.solutions.iter().zip(&series2.solutions) {
            assert_eq!(bits(&a.indirect), bits(&b.indirect));
            assert_eq!(a.stats.residual.to_bits(), b.stats.residual.to_bits());
        }
        assert!(!partial_path(&dir).exists());
        // Saving again replaces the bake.
        let mut other = series.clone();
        other.solutions[1].indirect[0] = Vec3::splat(42.0);
        save(&dir, &cornell(), &s, &other).unwrap();
        assert_eq!(load(&dir).unwrap().1, other);
    }

    #[test]
    fn refuses_to_replace_a_directory_that_is_not_a_bake() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("mine");
        fs::create_dir(&dir).unwrap();
        fs::write(dir.join("notes.txt"), "keep me").unwrap();
        let scene = cornell();
        let series = run(&scene, 0.0, |_, _| Vec3::ONE);
        let e = save(&dir, &scene, &Simplified::whole(&scene), &series).unwrap_err();
        assert!(
            format!("{e:#}").contains("refusing to replace")
                && format!("{e:#}").contains("notes.txt"),
            "{e:#}"
        );
        assert!(dir.join("notes.txt").exists());
    }

    #[test]
    fn unfinished_bake_is_not_taken_for_a_finished_one() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("cb.bake");
        baked(&dir);
        fs::rename(&dir, partial_path(&dir)).unwrap();
        let e = format!("{:#}", load(&dir).unwrap_err());
        assert!(e.contains("never finished"), "{e}");
    }

    fn expect_error(dir: &Path, file: &str, fragments: &[&str]) {
        let e = format!("{:#}", load(dir).unwrap_err());
        assert!(e.contains(file), "error does not name {file}: {e}");
        for f in fragments {
            assert!(e.contains(f), "error lacks `{f}`: {e}");
        }
    }

    #[test]
    fn damaged_files_give_errors_naming_file_and_field() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("cb.bake");
        baked(&dir);
        let manifest = dir.join(store::MANIFEST);
        let original = fs::read_to_string(&manifest).unwrap();

        // Truncated binary file.
        let irr = dir.join("irradiance.bin");
        let bytes = fs::read(&irr).unwrap();
        fs::write(&irr, &bytes[..bytes.len() - 5]).unwrap();
        expect_error(&dir, "irradiance.bin", &["truncated", "files.irradiance"]);

        // One flipped bit.
        let mut flipped = bytes.clone();
        flipped[100] ^= 0x10;
        fs::write(&irr, &flipped).unwrap();
        expect_error(&dir, "irradiance.bin", &["corrupt", "fnv1a64"]);
        fs::write(&irr, &bytes).unwrap();
        load(&dir).unwrap();

        // Wrong version.
        let v = original.replace("version = 4", "version = 99");
        assert_ne!(v, original);
        fs::write(&manifest, v).unwrap();
        expect_error(&dir, "manifest.toml", &["version", "99"]);

        // A missing field.
        let cut: String = original
            .lines()
            .filter(|l| !l.starts_with("quality"))
            .collect::<Vec<_>>()
            .join("\n");
        fs::write(&manifest, cut).unwrap();
        expect_error(&dir, "manifest.toml", &["quality"]);

        // Not TOML at all.
        fs::write(&manifest, "\u{0}\u{1}garbage").unwrap();
        expect_error(&dir, "manifest.toml", &[]);

        // Left-out triangles out of order, with a checksum that fits.
        let pruned = dir.join("pruned.bin");
        let bytes = fs::read(&pruned).unwrap();
        let mut swapped = bytes[8..16].to_vec();
        swapped.extend_from_slice(&bytes[..8]);
        swapped.extend_from_slice(&bytes[16..]);
        fs::write(&pruned, &swapped).unwrap();
        let sum = |b: &[u8]| rangewalk::checksum::hex(rangewalk::checksum::fnv1a64(b));
        fs::write(&manifest, original.replace(&sum(&bytes), &sum(&swapped))).unwrap();
        expect_error(&dir, "pruned.bin", &["ascend"]);
        fs::write(&pruned, &bytes).unwrap();

        // Missing binary file.
        fs::write(&manifest, &original).unwrap();
        fs::remove_file(dir.join("records.bin")).unwrap();
        expect_error(&dir, "records.bin", &[]);
    }
}
