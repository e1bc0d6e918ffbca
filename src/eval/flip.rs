//! NVIDIA FLIP, the perceptual image difference the paper names as its
//! missing metric, computed by the reference implementation (the Python
//! package `flip-evaluator`) in the project's virtual environment.
//!
//! Images go to the package as raw little-endian `float32` files (`H x W x 3`,
//! linear RGB) and come back as one mean per pair, and where asked for, the
//! per-pixel error map in FLIP's own colour map; one Python process serves
//! a whole batch, so the interpreter starts once per experiment stage rather
//! than once per frame. Radiance is high dynamic range, so HDR-FLIP is used:
//! it tone-maps both images at the exposures the reference spans and keeps
//! the worst difference per pixel.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};

use anyhow::{bail, ensure, Context, Result};
use glam::Vec3;

/// Exit status of the script when the package (or numpy) cannot be
/// imported; anything else non-zero is a failure inside FLIP.
const MISSING: i32 = 3;

const SCRIPT: &str = r#"
import json, sys
try:
    import numpy as np
    import flip_evaluator as flip
except ImportError as e:
    sys.stderr.write("%s\n" % e)
    sys.exit(3)
if len(sys.argv) > 1 and sys.argv[1] == "--check":
    sys.exit(0)
for job in json.load(sys.stdin):
    shape = (job["height"], job["width"], 3)
    ref = np.fromfile(job["reference"], dtype="<f4").reshape(shape)
    test = np.fromfile(job["test"], dtype="<f4").reshape(shape)
    err, mean, _ = flip.evaluate(ref, test, "HDR", applyMagma=bool(job["map"]))
    if job["map"]:
        np.ascontiguousarray(err, dtype="<f4").tofile(job["map"])
    print(repr(float(mean)), flush=True)
"#;

/// One pair's FLIP: its mean and its per-pixel error map.
#[derive(Clone, Debug, PartialEq)]
pub struct FlipMap {
    pub mean: f64,
    /// The error map in FLIP's colour map (magma: black for no visible
    /// difference, through purple and orange to pale yellow at 1), as
    /// 8-bit sRGB `RGBRGB...`, row-major: the bytes FLIP's own tool writes.
    pub rgb: Vec<u8>,
}

/// A Python interpreter known to have `flip_evaluator` and numpy.
#[derive(Clone, Debug)]
pub struct Flip {
    python: PathBuf,
}

impl Flip {
    /// The interpreter named by `RANGEWALK_PYTHON`, else `./.venv/bin/python`
    /// (what `make deps` creates).
    pub fn locate() -> Result<Flip> {
        let python = std::env::var_os("RANGEWALK_PYTHON")
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from(".venv/bin/python"));
        Flip::at(python)
    }

    /// Checks that `python` runs and imports the package.
    pub fn at(python: impl Into<PathBuf>) -> Result<Flip> {
        let python = python.into();
        let out = Command::new(&python)
            .args(["-c", SCRIPT, "--check"])
            .stdin(Stdio::null())
            .output()
            .map_err(|e| missing_python(&python, &e))?;
        if out.status.code() == Some(MISSING) {
            bail!(
                "{} cannot import NVIDIA FLIP ({}): run `make deps` to install \
                 flip-evaluator and numpy into .venv, or point RANGEWALK_PYTHON at a Python that has them",
                python.display(),
                String::from_utf8_lossy(&out.stderr).trim()
            );
        }
        ensure!(
            out.status.success(),
            "{} failed while checking for NVIDIA FLIP: {}",
            python.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        );
        Ok(Flip { python })
    }

    /// Mean HDR-FLIP of `test` against `reference` (linear RGB radiance,
    /// row-major, `width x height`): 0 for identical images, at most 1.
    pub fn hdr_mean(
        &self,
        width: u32,
        height: u32,
        reference: &[Vec3],
        test: &[Vec3],
    ) -> Result<f64> {
        Ok(self.hdr_means(width, height, &[(reference, test)])?[0])
    }

    /// [`Flip::hdr_mean`] of every `(reference, test)` pair, in one run of
    /// the interpreter.
    pub fn hdr_means(
        &self,
        width: u32,
        height: u32,
        pairs: &[(&[Vec3], &[Vec3])],
    ) -> Result<Vec<f64>> {
        Ok(self
            .run(width, height, pairs, false)?
            .into_iter()
            .map(|m| m.mean)
            .collect())
    }

    /// The mean HDR-FLIP and the error map of every `(reference, test)`
    /// pair, in one run of the interpreter: what a viewer would notice,
    /// and where.
    pub fn hdr_maps(
        &self,
        width: u32,
        height: u32,
        pairs: &[(&[Vec3], &[Vec3])],
    ) -> Result<Vec<FlipMap>> {
        self.run(width, height, pairs, true)
    }

    /// FLIP of every pair, with error maps when `maps` (else their `rgb`
    /// is empty).
    fn run(
        &self,
        width: u32,
        height: u32,
        pairs: &[(&[Vec3], &[Vec3])],
        maps: bool,
    ) -> Result<Vec<FlipMap>> {
        if pairs.is_empty() {
            return Ok(Vec::new());
        }
        let n = width as usize * height as usize;
        let dir = ScratchDir::new()?;
        let mut jobs = Vec::with_capacity(pairs.len());
        for (k, (reference, test)) in pairs.iter().enumerate() {
            check(reference, n, width, height, "reference", k)?;
            check(test, n, width, height, "test", k)?;
            // HDR-FLIP takes its exposure range from the reference's
            // luminance; a black reference has none (the package exits).
            ensure!(
                reference.iter().any(|c| c.max_element() > 0.0),
                "FLIP pair {k}: the reference is black everywhere; FLIP is undefined for it"
            );
            let (r, t) = (
                dir.0.join(format!("{k}-ref.f32")),
                dir.0.join(format!("{k}-test.f32")),
            );
            write_f32(&r, reference)?;
            write_f32(&t, test)?;
            let map = maps.then(|| dir.0.join(format!("{k}-map.f32")));
            jobs.push(serde_json::json!({
                "width": width, "height": height,
                "reference": r, "test": t, "map": map,
            }));
        }
        let mut child = Command::new(&self.python)
            .args(["-c", SCRIPT])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| missing_python(&self.python, &e))?;
        child
            .stdin
            .take()
            .context("FLIP: no stdin")?
            .write_all(serde_json::to_string(&jobs)?.as_bytes())
            .context("FLIP: sending the job list")?;
        let out = child
            .wait_with_output()
            .context("FLIP: waiting for Python")?;
        let stdout = String::from_utf8_lossy(&out.stdout);
        ensure!(
            out.status.success(),
            "NVIDIA FLIP ({}) failed: {}{}",
            self.python.display(),
            String::from_utf8_lossy(&out.stderr).trim(),
            stdout.trim()
        );
        let means = stdout
            .lines()
            .map(|l| {
                l.trim()
                    .parse::<f64>()
                    .with_context(|| format!("FLIP printed `{l}`, not a number"))
            })
            .collect::<Result<Vec<f64>>>()?;
        ensure!(
            means.len() == pairs.len() && means.iter().all(|m| m.is_finite()),
            "FLIP returned {:?} for {} image pairs",
            means,
            pairs.len()
        );
        means
            .into_iter()
            .zip(&jobs)
            .map(|(mean, job)| {
                let rgb = match job["map"].as_str() {
                    Some(path) => read_map(Path::new(path), n)?,
                    None => Vec::new(),
                };
                Ok(FlipMap { mean, rgb })
            })
            .collect()
    }
}

/// A colour-mapped error map of `n` pixels as FLIP wrote it (`float32`
/// sRGB in [0, 1]), in bytes as FLIP's tool writes them: `round(255 v)`.
fn read_map(path: &Path, n: usize) -> Result<Vec<u8>> {
    let bytes =
        std::fs::read(path).with_context(|| format!("reading FLIP's map {}", path.display()))?;
    ensure!(
        bytes.len() == 4 * 3 * n,
        "FLIP wrote {} bytes of error map for {n} pixels",
        bytes.len()
    );
    Ok(bytes
        .chunks_exact(4)
        .map(|b| {
            let v = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            (255.0 * v.clamp(0.0, 1.0)).round() as u8
        })
        .collect())
}

fn missing_python(python: &Path, e: &std::io::Error) -> anyhow::Error {
    anyhow::anyhow!(
        "cannot run Python at {} ({e}): run `make deps` to create .venv with flip-evaluator, \
         or set RANGEWALK_PYTHON to a Python that has it",
        python.display()
    )
}

fn check(img: &[Vec3], n: usize, width: u32, height: u32, what: &str, k: usize) -> Result<()> {
    ensure!(
        img.len() == n && n > 0,
        "FLIP pair {k}: the {what} image has {} pixels, not {width}x{height}",
        img.len()
    );
    if let Some(i) = img
        .iter()
        .position(|c| !c.is_finite() || c.min_element() < 0.0)
    {
        bail!(
            "FLIP pair {k}: {what} pixel {i} is {}; HDR-FLIP needs finite non-negative radiance",
            img[i]
        );
    }
    Ok(())
}

fn write_f32(path: &Path, img: &[Vec3]) -> Result<()> {
    let bytes: Vec<u8> = img
        .iter()
        .flat_map(|c| c.to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
}

/// A private folder under the system's temporary directory, removed when
/// dropped (also on errors).
struct ScratchDir(PathBuf);

impl ScratchDir {
    fn new() -> Result<Self> {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let dir = std::env::temp_dir().join(format!(
            "rangewalk-flip-{}-{}",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok(Self(dir))
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        // Best effort: a leftover folder in the temporary directory harms
        // nothing, and the error being returned (if any) matters more.
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The project's FLIP: `make deps` installs it, so its absence is a
    /// failure, not a reason to pass.
    fn flip() -> Flip {
        Flip::locate().unwrap_or_else(|e| panic!("FLIP is required by this test: {e:#}"))
    }

    fn pattern(w: u32, h: u32) -> Vec<Vec3> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                Vec3::new(0.2 + 0.1 * x, 0.5 + 0.05 * y, 1.0 + ((x + y) % 3.0))
            })
            .collect()
    }

    #[test]
    fn identical_images_score_zero_and_different_ones_do_not() {
        let f = flip();
        let a = pattern(24, 16);
        let b: Vec<Vec3> = a
            .iter()
            .enumerate()
            .map(|(i, c)| if i % 7 == 0 { *c * 3.0 } else { *c })
            .collect();
        let m = f.hdr_means(24, 16, &[(&a, &a), (&a, &b)]).unwrap();
        assert_eq!(m[0], 0.0);
        assert!(m[1] > 0.01 && m[1] <= 1.0, "FLIP {}", m[1]);
        // One pair alone gives the same answer as in a batch.
        assert_eq!(f.hdr_mean(24, 16, &a, &b).unwrap(), m[1]);
    }

    #[test]
    fn error_maps_show_where_images_differ() {
        let f = flip();
        let a = pattern(24, 16);
        // A bright square of 6 x 6 pixels from (8, 4).
        let inside = |i: usize| (8..14).contains(&(i % 24)) && (4..10).contains(&(i / 24));
        let b: Vec<Vec3> = a
            .iter()
            .enumerate()
            .map(|(i, c)| if inside(i) { *c * 8.0 } else { *c })
            .collect();
        let maps = f.hdr_maps(24, 16, &[(&a, &a), (&a, &b)]).unwrap();
        // The means are those without maps.
        let means = f.hdr_means(24, 16, &[(&a, &a), (&a, &b)]).unwrap();
        assert_eq!(maps.iter().map(|m| m.mean).collect::<Vec<_>>(), means);
        for m in &maps {
            assert_eq!(m.rgb.len(), 24 * 16 * 3);
        }
        // No difference is magma's darkest colour everywhere: (0.001462,
        // 0.000466, 0.013866) in FLIP's map, bytes (0, 0, 4).
        assert!(
            maps[0].rgb.chunks(3).all(|p| p == [0, 0, 4]),
            "{:?}",
            &maps[0].rgb[..6]
        );
        // The square is brighter in the map than the corner far from it.
        let brightness = |i: usize| {
            maps[1].rgb[3 * i..3 * i + 3]
                .iter()
                .map(|&v| v as u32)
                .sum::<u32>()
        };
        assert!(brightness(7 * 24 + 11) > brightness(15 * 24 + 23) + 100);
    }

    #[test]
    fn missing_python_names_the_fix() {
        let e = Flip::at("/nonexistent/python").unwrap_err().to_string();
        assert!(
            e.contains("make deps") && e.contains("/nonexistent/python"),
            "{e}"
        );
    }

    #[test]
    fn undefined_inputs_are_errors_before_python_runs() {
        let f = Flip {
            python: PathBuf::from("/nonexistent/python"),
        };
        let a = vec![Vec3::ONE; 4];
        let black = vec![Vec3::ZERO; 4];
        let e = f.hdr_mean(2, 2, &black, &a).unwrap_err().to_string();
        assert!(e.contains("black"), "{e}");
        let mut neg = a.clone();
        neg[1].x = -1.0;
        let e = f.hdr_mean(2, 2, &a, &neg).unwrap_err().to_string();
        assert!(e.contains("pixel 1"), "{e}");
        assert!(f.hdr_mean(3, 2, &a, &a).is_err());
    }
}
