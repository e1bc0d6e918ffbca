//! The user's one knob, `q ∈ [0, 1]`: every subdivision decision of the
//! planner (views, times) and of the object-space stages (simplification,
//! solves) follows from it, higher being finer and slower.
//!
//! A value of this type is in range by construction, so it is checked once,
//! where it enters (the command line, the C API, a file), and carried whole
//! from there: the stages never see a bare `f32` they would have to check
//! again. Files keep it as a plain number.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// A quality in `[0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd, Serialize, Deserialize)]
#[serde(try_from = "f32", into = "f32")]
pub struct Quality(f32);

/// Why a number is not a quality; names the value, not where it came from
/// (the front end that read it says that).
#[derive(Clone, Debug, PartialEq)]
pub enum QualityError {
    NotANumber(String),
    OutOfRange(f32),
}

impl fmt::Display for QualityError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotANumber(s) => write!(f, "quality `{s}` is not a number"),
            Self::OutOfRange(q) => write!(f, "quality {q} is outside [0, 1]"),
        }
    }
}

impl std::error::Error for QualityError {}

impl Quality {
    /// Where none is given: `rangewalk radiosity`, `render --indirect
    /// radiosity`, the C API's bake options.
    pub const DEFAULT: Quality = Quality(0.5);

    pub fn new(q: f32) -> Result<Self, QualityError> {
        if (0.0..=1.0).contains(&q) {
            Ok(Self(q))
        } else {
            Err(QualityError::OutOfRange(q))
        }
    }

    pub fn get(self) -> f32 {
        self.0
    }
}

impl Default for Quality {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl TryFrom<f32> for Quality {
    type Error = QualityError;

    fn try_from(q: f32) -> Result<Self, QualityError> {
        Self::new(q)
    }
}

impl From<Quality> for f32 {
    fn from(q: Quality) -> f32 {
        q.0
    }
}

impl FromStr for Quality {
    type Err = QualityError;

    fn from_str(s: &str) -> Result<Self, QualityError> {
        let q: f32 = s
            .trim()
            .parse()
            .map_err(|_| QualityError::NotANumber(s.to_string()))?;
        Self::new(q)
    }
}

impl fmt::Display for Quality {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.fmt(f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_unit_interval_is_a_quality() {
        for q in [0.0, 0.5, 1.0] {
            assert_eq!(Quality::new(q).unwrap().get(), q);
        }
        for q in [-0.01, 1.01, f32::NAN, f32::INFINITY] {
            let e = Quality::new(q).unwrap_err().to_string();
            assert!(
                e.starts_with("quality ") && e.ends_with("is outside [0, 1]"),
                "{e}"
            );
        }
        assert_eq!("0.25".parse::<Quality>().unwrap().get(), 0.25);
        assert_eq!(
            "high".parse::<Quality>().unwrap_err().to_string(),
            "quality `high` is not a number"
        );
    }

    #[test]
    fn files_hold_it_as_a_number_and_are_checked_on_reading() {
        let q = Quality::new(0.3).unwrap();
        assert_eq!(serde_json::to_string(&q).unwrap(), "0.3");
        assert_eq!(serde_json::from_str::<Quality>("0.3").unwrap(), q);
        let e = serde_json::from_str::<Quality>("1.5")
            .unwrap_err()
            .to_string();
        assert!(e.contains("quality 1.5 is outside [0, 1]"), "{e}");
    }
}
