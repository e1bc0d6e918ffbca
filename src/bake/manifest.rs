//! The bake directory's `manifest.json`: what was baked from what, with
//! which settings, and each image's checksum once the bake is complete.
//!
//! While a bake runs (on one machine or as shards on many), each finished
//! image has a checksum file beside it, written after the image; the
//! manifest gathers them when the last image is done. An image without a
//! matching checksum file is unfinished or damaged, and is rendered again.
//! Checksums are of the decoded content, not of the file's bytes: the
//! pure-Rust EXR writer orders header attributes differently every time.

use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};

pub use crate::checksum::hex;
use crate::image;
use crate::plan::Plan;
use crate::scene::hash::ContentHash;

use super::window::BaseWindow;
use super::{Sampling, Settings};
use crate::render::noise::NoiseReport;

/// Identifies a base-image bake manifest.
pub const FORMAT: &str = "rangewalk-base-images";
/// Bumped whenever the layout changes. Version 8's planes files hold what
/// synthesis keeps of a base (planes file version 3: radiance unmixed
/// beside the lights in half floats, distances, ids), version 7 compresses
/// the planes files (planes file version 2; version 6's uncompressed ones,
/// version 1, are still read), version 6 gives each image a planes file
/// ([`planes_path`]), version 5 records each view's window
/// (partial base images), version 4 the sampling settings and each
/// image's noise, version 3 the planning settings; versions 2 to 7 are
/// read too (see [`Manifest::read`]); others are refused.
pub const VERSION: u32 = 8;
/// The first version whose images have planes files.
pub const PLANES_SINCE: u32 = 6;
/// The first version whose planes files hold bases (planes file version 3)
/// rather than range images.
pub const BASE_PLANES_SINCE: u32 = 8;
pub const MANIFEST: &str = "manifest.json";
/// The object-space bake (radiosity), when indirect light comes from it.
pub const RADIOSITY: &str = "radiosity";
pub const IMAGES: &str = "images";

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub format: String,
    pub version: u32,
    /// The scene file the bake was started from (absolute where it could
    /// be resolved), which `synth` and `walk` load.
    pub scene: PathBuf,
    pub scene_hash: ContentHash,
    pub settings: Settings,
    /// Absent before version 4, whose bakes sampled every pixel alike.
    #[serde(default = "flat")]
    pub sampling: Sampling,
    pub plan: Plan,
    /// Each view's window: the pixels of the whole `settings.size`²
    /// projection its images hold (see [`super::window`]). Absent before
    /// version 5, whose images are whole.
    #[serde(default)]
    pub windows: Vec<BaseWindow>,
    /// Every (view, time) image, in the order shards count them.
    pub images: Vec<ImageEntry>,
    /// Whether every image is rendered and its checksum recorded here.
    pub complete: bool,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImageEntry {
    /// Index into `plan.views`.
    pub view: usize,
    /// Index into that view's `times`.
    pub time_index: usize,
    pub time: f32,
    /// Path relative to the bake directory.
    pub file: String,
    /// FNV-1a 64 of the image's content (16 hex digits: every channel and
    /// the `rangewalk:*` attributes, as `image::exr_content_hash`), once
    /// the bake is complete.
    pub fnv1a64: Option<String>,
    /// The noise the image reached (`render::noise`), once the bake is
    /// complete; absent before version 4.
    #[serde(default)]
    pub noise: Option<NoiseReport>,
}

fn flat() -> Sampling {
    Sampling::FLAT
}

impl Manifest {
    pub fn read(dir: &Path) -> Result<Manifest> {
        let path = dir.join(MANIFEST);
        let text =
            fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
        let m: Manifest = serde_json::from_str(&text)
            .with_context(|| format!("{}: not a base-image bake manifest", path.display()))?;
        if m.format != FORMAT {
            bail!(
                "{}: `format` is `{}`, expected `{FORMAT}`",
                path.display(),
                m.format
            );
        }
        let mut m = m;
        if m.version < 5 && m.windows.is_empty() {
            // Images of older bakes hold the whole projection: a window
            // as large as the image is exactly that.
            m.windows = vec![BaseWindow::whole(m.settings.size); m.plan.views.len()];
        }
        match m.version {
            VERSION | 3..=7 => {}
            // Version 2 did not record the planning settings, but its plans
            // did, as made: the id-image side, whether one master list, and
            // the view fitness (ids, the only one there was before plans
            // recorded it). So an older bake resumes, or is refused, as a
            // new one would be.
            2 => {
                let quality = m.settings.quality;
                let side = m.plan.resolution;
                m.settings.planning = super::Planning {
                    // As a new manifest records it: `None` for the default.
                    resolution: (side != crate::plan::default_resolution(quality)).then_some(side),
                    master_list: m.plan.master_list,
                    view_fitness: m.plan.view_fitness,
                    whole: false,
                }
            }
            v => bail!(
                "{}: `version` is {v}, this rangewalk reads versions 2 to {VERSION}: \
                 bake it again into a new directory with this rangewalk, or use the rangewalk that made it",
                path.display(),
            ),
        }
        m.check().with_context(|| format!("{}", path.display()))?;
        Ok(m)
    }

    /// What readers rely on and serde cannot check: every image names a
    /// view and time of the plan and a file inside the bake directory (a
    /// manifest is data, and must not point a reader at `/etc/passwd` or
    /// `../elsewhere`), and every view's times are finite and increasing,
    /// as the interpolation between them assumes.
    fn check(&self) -> Result<()> {
        let views = &self.plan.views;
        for (v, view) in views.iter().enumerate() {
            if !view.position.is_finite() {
                bail!("`plan.views[{v}].position` {} is not finite", view.position);
            }
            if !view.times.iter().all(|t| t.is_finite()) {
                bail!(
                    "`plan.views[{v}].times` {:?} are not all finite",
                    view.times
                );
            }
            if !view.times.windows(2).all(|w| w[0] < w[1]) {
                bail!(
                    "`plan.views[{v}].times` {:?} are not in increasing order",
                    view.times
                );
            }
        }
        if self.windows.len() != views.len() {
            bail!(
                "`windows` has {} entries for the plan's {} views",
                self.windows.len(),
                views.len()
            );
        }
        for (v, w) in self.windows.iter().enumerate() {
            w.check(self.settings.size)
                .with_context(|| format!("`windows[{v}]`"))?;
        }
        for (k, e) in self.images.iter().enumerate() {
            let Some(view) = views.get(e.view) else {
                bail!(
                    "`images[{k}].view` {} is not one of the plan's {} views",
                    e.view,
                    views.len()
                );
            };
            if view.times.get(e.time_index) != Some(&e.time) {
                bail!(
                    "`images[{k}]`: time {} (index {}) is not one of view {}'s times {:?}",
                    e.time,
                    e.time_index,
                    e.view,
                    view.times
                );
            }
            let inside = Path::new(&e.file)
                .components()
                .all(|c| matches!(c, std::path::Component::Normal(_)));
            if e.file.is_empty() || !inside {
                bail!(
                    "`images[{k}].file` `{}` is not a path inside the bake directory",
                    e.file
                );
            }
        }
        Ok(())
    }

    /// Whether each image has a planes file beside it, which synthesis
    /// reads instead of the EXR (bakes before version 6 have none).
    pub fn has_planes(&self) -> bool {
        self.version >= PLANES_SINCE
    }

    /// Whether the planes files hold what synthesis keeps of each base
    /// (`image::planes_file::read_base`) rather than range images.
    pub fn has_base_planes(&self) -> bool {
        self.version >= BASE_PLANES_SINCE
    }

    /// Writes the manifest atomically (a reader sees the old or the new one).
    pub fn write(&self, dir: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self).context("encoding the bake manifest")?;
        crate::output::write_file(&dir.join(MANIFEST), text)
    }
}

/// The checksum file beside an image.
pub fn checksum_path(image: &Path) -> PathBuf {
    let mut name = image.as_os_str().to_os_string();
    name.push(".fnv1a64");
    PathBuf::from(name)
}

/// The planes file beside an image (`image::planes_file`): what synthesis
/// reads of it without decoding the EXR.
pub fn planes_path(image: &Path) -> PathBuf {
    let mut name = image.as_os_str().to_os_string();
    name.push(".planes");
    PathBuf::from(name)
}

/// The image's checksum: of its content (channels and metadata), not of
/// its bytes, so that it is the same whichever EXR writer made the file.
/// `None` where the file is missing or cannot be read (cut short, corrupt).
pub fn checksum_of(path: &Path) -> Option<String> {
    image::exr_content_hash(path).ok().map(hex)
}

/// Whether the image is finished and undamaged: it reads, and its content
/// matches the checksum recorded after it was written (`expected` where the
/// manifest already holds it, else the checksum file); with `planes`, its
/// planes file reads too, every chunk matching, made with that image.
pub fn verify(path: &Path, expected: Option<&str>, planes: bool) -> bool {
    path.exists()
        && recorded(path, expected).is_some_and(|sum| {
            checksum_of(path).as_ref() == Some(&sum)
                && (!planes || image::planes_file::verify(&planes_path(path), &sum).is_ok())
        })
}

/// The checksum recorded for an image: the manifest's (`expected`) where
/// it has one, else the checksum file's, if it was written.
pub fn recorded(path: &Path, expected: Option<&str>) -> Option<String> {
    match expected {
        Some(sum) => Some(sum.to_string()),
        None => fs::read_to_string(checksum_path(path))
            .ok()
            .map(|s| s.trim().to_string()),
    }
}

/// Whether `name` is that of a temporary file of `output`'s writers. A
/// killed run leaves them behind; a bake removes them when it alone works
/// on the directory.
pub fn is_temporary(name: &std::ffi::OsStr) -> bool {
    name.to_str()
        .is_some_and(|n| crate::output::temporary_for(n).is_some())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::PlannedView;
    use crate::quality::Quality;
    use glam::Vec3;

    fn entry(view: usize, time_index: usize, time: f32, file: &str) -> ImageEntry {
        ImageEntry {
            view,
            time_index,
            time,
            file: file.into(),
            fnv1a64: None,
            noise: None,
        }
    }

    fn view(position: Vec3, times: &[f32]) -> Vec<PlannedView> {
        vec![PlannedView {
            position,
            times: times.to_vec(),
        }]
    }

    fn check(views: Vec<PlannedView>, e: ImageEntry) -> Result<(), String> {
        let manifest = Manifest {
            format: FORMAT.into(),
            version: VERSION,
            scene: PathBuf::from("scene.toml"),
            scene_hash: ContentHash {
                total: String::new(),
                text: String::new(),
                meshes: Vec::new(),
                materials: Vec::new(),
            },
            settings: Settings {
                quality: Quality::new(0.5).unwrap(),
                size: 4,
                spp: 1,
                projection: super::super::BaseProjection::Sphere,
                indirect: super::super::IndirectSource::Path,
                seed: 0,
                backend: crate::accel::Backend::Bvh,
                max_depth: None,
                planning: super::super::Planning::default(),
            },
            sampling: Sampling::FLAT,
            windows: vec![BaseWindow::whole(4); views.len()],
            plan: Plan {
                views,
                ..Plan::default()
            },
            images: vec![e],
            complete: false,
        };
        manifest.check().map_err(|e| e.to_string())
    }

    #[test]
    fn images_must_name_the_plan_and_stay_inside_the_bake() {
        let good = || view(Vec3::ZERO, &[0.0, 1.0]);
        check(good(), entry(0, 1, 1.0, "images/a.exr")).unwrap();
        for (views, e, needle) in [
            (
                good(),
                entry(1, 0, 0.0, "a.exr"),
                "not one of the plan's 1 views",
            ),
            (good(), entry(0, 2, 1.0, "a.exr"), "index 2"),
            (good(), entry(0, 1, 0.5, "a.exr"), "time 0.5"),
            (good(), entry(0, 0, 0.0, "/etc/passwd"), "inside the bake"),
            (good(), entry(0, 0, 0.0, "../x.exr"), "inside the bake"),
            (good(), entry(0, 0, 0.0, ""), "inside the bake"),
            (
                view(Vec3::ZERO, &[1.0, 0.0]),
                entry(0, 0, 1.0, "a.exr"),
                "increasing",
            ),
            (
                view(Vec3::NAN, &[0.0]),
                entry(0, 0, 0.0, "a.exr"),
                "position",
            ),
        ] {
            let e = check(views, e).unwrap_err();
            assert!(e.contains(needle), "`{needle}` not in: {e}");
        }
    }
}
