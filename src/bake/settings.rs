//! What decides a bake's images besides its sampling: the settings a
//! bake is resumed (or extended by shards) only with, and which share of
//! the images a run renders.

use serde::{Deserialize, Serialize};

use crate::accel::Backend;
use crate::plan::{self, ViewFitness};
use crate::quality::Quality;

#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    Serialize,
    Deserialize,
    strum::Display,
    strum::EnumString,
    strum::IntoStaticStr,
    strum::VariantArray,
    strum::EnumMessage,
)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum BaseProjection {
    /// Every direction, equal-area octahedral: the viewer may turn freely.
    Sphere,
    /// 180° angular fisheye along the scene's view direction (the paper's).
    Fisheye,
}

/// Where a bake's diffuse indirect light comes from. The default is the
/// gather: frames from gathered bases had the lowest FLIP and block error
/// on the Cornell box and the studio (`docs/synthesis.md`, "Bases'
/// indirect light"), for about three to four times the bake's time.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    Serialize,
    Deserialize,
    strum::Display,
    strum::EnumString,
    strum::IntoStaticStr,
    strum::VariantArray,
    strum::EnumMessage,
)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum IndirectSource {
    /// Looked up from radiosity records interpolated in time (§4.3–4.4).
    Radiosity,
    /// Radiosity records seen through one traced bounce at the surfaces a base shows (a final gather): where surfaces meet, the darkening the records miss.
    #[default]
    Gather,
    /// Traced: one diffuse bounce per sample continued by the path tracer.
    Path,
}

impl IndirectSource {
    /// Whether the bake solves for radiosity records.
    pub fn uses_records(self) -> bool {
        matches!(self, Self::Radiosity | Self::Gather)
    }
}

/// Everything that decides a bake's images besides its [`Sampling`](super::Sampling). A
/// bake is resumed or extended (by shards) only with the same settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    pub quality: Quality,
    /// Side of the square base images.
    pub size: u32,
    pub spp: u32,
    pub projection: BaseProjection,
    pub indirect: IndirectSource,
    pub seed: u64,
    pub backend: Backend,
    pub max_depth: Option<u32>,
    /// How the plan (views and times) is made: a resume reuses the plan it
    /// finds, so it must have been made the way this run would make it.
    #[serde(default)]
    pub planning: Planning,
}

/// The planner's options besides the quality (`rangewalk bake
/// --resolution`, `--master-list`, `--view-fitness`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Planning {
    /// Side of the id-images; `None`: the quality's default (naming the
    /// default resumes a bake made without naming it, see
    /// [`Settings::resolved`]).
    pub resolution: Option<u32>,
    pub master_list: bool,
    pub view_fitness: ViewFitness,
    /// Whether every base keeps its whole projection (`--whole-bases`),
    /// not only the window that may see the scene ([`window`](super::window)).
    #[serde(default)]
    pub whole: bool,
}

impl Settings {
    /// These settings with the planner's id-image side written out: two
    /// settings make the same bake when their resolved forms are equal.
    pub fn resolved(&self) -> Settings {
        let mut s = *self;
        s.planning.resolution = Some(
            self.planning
                .resolution
                .unwrap_or_else(|| plan::default_resolution(self.quality)),
        );
        s
    }
}

/// Which part of the images this run renders: every `count`-th image from
/// the `index`-th, in manifest order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

impl Shard {
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    pub fn owns(&self, k: usize) -> bool {
        k % self.count as usize == self.index as usize
    }
}

impl std::str::FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let err = || format!("shard `{s}` is not i/n with 0 <= i < n, e.g. 0/4");
        let (i, n) = s.split_once('/').ok_or_else(err)?;
        let (index, count) = (
            i.trim().parse::<u32>().map_err(|_| err())?,
            n.trim().parse::<u32>().map_err(|_| err())?,
        );
        if count == 0 || index >= count {
            return Err(err());
        }
        Ok(Shard { index, count })
    }
}
