//! Where and when base range images are rendered (paper §4.1, §4.2): id-images
//! and their fitness, base views by adaptive subdivision of the view space,
//! and time lists from the lights and from each base view.
//!
//! A [`Plan`] is plain data, written as JSON by `rangewalk plan` and stored in
//! every bake's manifest, so a bake can be checked against the plan it was
//! made from.

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// The base views of a scene and the times each is rendered at.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// The quality `q` every subdivision followed.
    pub quality: f32,
    /// Base views in a fixed order (bakes name images by view index).
    pub views: Vec<PlannedView>,
    /// The times direct light needs (from the lights' id-images), before
    /// any per-view refinement.
    pub light_times: Vec<f32>,
    /// Every planning step with the time it took.
    pub steps: Vec<Step>,
    /// What was left out and why (a static scene gets one time, ...).
    pub skipped: Vec<String>,
}

/// One base viewpoint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlannedView {
    pub position: Vec3,
    /// Strictly increasing scene times (s) of this view's base images.
    pub times: Vec<f32>,
}

/// One planning step and what it cost.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Step {
    pub name: String,
    pub seconds: f64,
}
