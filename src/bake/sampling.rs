//! How many samples a base pixel takes: `spp` at least, then more while
//! its estimated noise is above a target (`render::noise`), up to a limit.
//! A setting of the bake like `spp` (a resume must use the same), and each
//! image's report of the noise it reached, kept beside the image.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};

use crate::render::noise::{NoiseReport, NoiseTarget};

/// The noise target of `rangewalk bake` and the C ABI when none is given.
/// Chosen by measurement on the Cornell box demo bake: see
/// `docs/bake-format.md`, "Sampling to a noise target".
pub const DEFAULT_NOISE: f32 = 0.02;
/// The sample limit, as a multiple of `spp`, when none is given.
pub const DEFAULT_MAX_SPP_FACTOR: u32 = 16;

/// The bake's sampling settings besides `Settings::spp`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sampling {
    /// Relative standard error of a pixel's mean luminance at which it
    /// stops; `None`: every pixel takes `spp` samples (bakes before
    /// manifest version 4 read so).
    pub noise: Option<f32>,
    /// Most samples a pixel takes; `None`: [`DEFAULT_MAX_SPP_FACTOR`] ×
    /// `spp`.
    pub max_spp: Option<u32>,
}

impl Default for Sampling {
    fn default() -> Self {
        Sampling {
            noise: Some(DEFAULT_NOISE),
            max_spp: None,
        }
    }
}

impl Sampling {
    /// Every pixel takes `spp` samples.
    pub const FLAT: Sampling = Sampling {
        noise: None,
        max_spp: None,
    };

    /// Refuses values that cannot make a bake with `spp` samples at least.
    /// `name` turns a field's name (`max_spp`) into what the caller calls
    /// it (`--max-spp`, `options->max_spp`).
    pub fn check(&self, spp: u32, name: &dyn Fn(&str) -> String) -> Result<()> {
        if spp == 0 {
            bail!("{} 0: a pixel needs at least 1 sample", name("spp"));
        }
        match (self.noise, self.max_spp) {
            (Some(noise), _) => check_noise(noise, name)?,
            (None, Some(m)) => bail!(
                "{} {m} applies with a {} target only; without one every pixel takes {} samples",
                name("max_spp"),
                name("noise"),
                name("spp")
            ),
            (None, None) => {}
        }
        if let Some(m) = self.max_spp {
            if m < spp {
                bail!(
                    "{} {m} is below {} {spp}: the limit cannot be under the minimum",
                    name("max_spp"),
                    name("spp")
                );
            }
        }
        Ok(())
    }

    /// What the renderer is asked for with `spp` samples at least: `None`
    /// where every pixel takes `spp` (no target, or a limit of `spp`). Two
    /// samplings make the same images when their targets are equal.
    pub fn target(&self, spp: u32) -> Option<NoiseTarget> {
        let relative = self.noise?;
        let max_spp = self
            .max_spp
            .unwrap_or_else(|| spp.saturating_mul(DEFAULT_MAX_SPP_FACTOR));
        (max_spp > spp).then_some(NoiseTarget { relative, max_spp })
    }

    /// The `rangewalk bake` options that give this sampling.
    pub fn describe(&self) -> String {
        match (self.noise, self.max_spp) {
            (None, _) => "--noise off".into(),
            (Some(n), None) => format!("--noise {n}"),
            (Some(n), Some(m)) => format!("--noise {n} --max-spp {m}"),
        }
    }
}

/// Refuses a noise target that is no relative error in (0, 1].
fn check_noise(noise: f32, name: &dyn Fn(&str) -> String) -> Result<()> {
    if !(noise > 0.0 && noise <= 1.0) {
        bail!(
            "{} {noise} is not a relative error in (0, 1] (0.02: 2 %)",
            name("noise")
        );
    }
    Ok(())
}

/// `rangewalk bake --noise`: a relative error, or `off`.
pub fn parse_noise(s: &str) -> Result<Option<f32>, String> {
    if s.trim().eq_ignore_ascii_case("off") {
        return Ok(None);
    }
    let v: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a number (a relative error such as 0.02) nor `off`"))?;
    check_noise(v, &|f| format!("--{f}")).map_err(|e| format!("{e}, nor `off`"))?;
    Ok(Some(v))
}

/// The file beside an image that holds its noise report, written after the
/// image and before its checksum file.
pub fn report_path(image: &Path) -> PathBuf {
    let mut name = image.as_os_str().to_os_string();
    name.push(".noise.json");
    PathBuf::from(name)
}

pub fn write_report(image: &Path, report: &NoiseReport) -> Result<()> {
    let text = serde_json::to_string_pretty(report).context("encoding a noise report")?;
    crate::output::write_file(&report_path(image), text)
}

/// The report beside an image; `None` where there is none (an image of an
/// older rangewalk) or it does not read.
pub fn read_report(image: &Path) -> Option<NoiseReport> {
    let text = std::fs::read_to_string(report_path(image)).ok()?;
    serde_json::from_str(&text).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_values_are_refused_naming_the_option_and_value() {
        for (s, needle) in [
            ("0", "--noise 0 "),
            ("-0.1", "--noise -0.1 "),
            ("NaN", "--noise NaN "),
            ("inf", "--noise inf "),
            ("1.5", "--noise 1.5 "),
            ("x", "`x` is not a number"),
        ] {
            let e = parse_noise(s).unwrap_err();
            assert!(e.contains(needle), "{s}: {e}");
        }
        assert_eq!(parse_noise("off"), Ok(None));
        assert_eq!(parse_noise("0.01"), Ok(Some(0.01)));
        let low = Sampling {
            noise: Some(0.02),
            max_spp: Some(4),
        };
        let flag = |f: &str| format!("--{}", f.replace('_', "-"));
        let e = low.check(8, &flag).unwrap_err().to_string();
        assert!(e.contains("--max-spp 4 is below --spp 8"), "{e}");
        let e = Sampling::default().check(0, &flag).unwrap_err().to_string();
        assert!(e.contains("--spp 0"), "{e}");
        let field = |f: &str| format!("options->{f}");
        let e = low.check(8, &field).unwrap_err().to_string();
        assert!(
            e.contains("options->max_spp 4 is below options->spp 8"),
            "{e}"
        );
        let alone = Sampling {
            noise: None,
            max_spp: Some(64),
        };
        let e = alone.check(8, &flag).unwrap_err().to_string();
        assert!(
            e.contains("--max-spp 64 applies with a --noise target only"),
            "{e}"
        );
    }

    #[test]
    fn a_limit_of_spp_samples_flat_and_the_default_limit_is_sixteen_times_spp() {
        let s = |noise, max_spp| Sampling { noise, max_spp };
        assert_eq!(s(Some(0.02), Some(8)).target(8), None);
        assert_eq!(s(None, None).target(8), None);
        assert_eq!(
            s(Some(0.02), None).target(8),
            Some(NoiseTarget {
                relative: 0.02,
                max_spp: 128
            })
        );
        assert_eq!(
            s(Some(0.02), None).target(8),
            s(Some(0.02), Some(128)).target(8)
        );
    }
}
