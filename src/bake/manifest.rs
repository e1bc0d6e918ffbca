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

use crate::image;
use crate::plan::Plan;
use crate::scene::hash::ContentHash;

use super::Settings;

/// Identifies a base-image bake manifest.
pub const FORMAT: &str = "rangewalk-base-images";
/// Bumped whenever the layout changes; other versions are refused.
pub const VERSION: u32 = 2;
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
    pub plan: Plan,
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
        if m.version != VERSION {
            bail!(
                "{}: `version` is {}, this rangewalk reads version {VERSION}",
                path.display(),
                m.version
            );
        }
        Ok(m)
    }

    /// Writes the manifest atomically (a reader sees the old or the new one).
    pub fn write(&self, dir: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self).context("encoding the bake manifest")?;
        write_atomically(&dir.join(MANIFEST), text.as_bytes())
    }
}

/// The checksum file beside an image.
pub fn checksum_path(image: &Path) -> PathBuf {
    let mut name = image.as_os_str().to_os_string();
    name.push(".fnv1a64");
    PathBuf::from(name)
}

/// A checksum as the manifest writes it: 16 hex digits.
pub fn hex(sum: u64) -> String {
    format!("{sum:016x}")
}

/// The image's checksum: of its content (channels and metadata), not of
/// its bytes, so that it is the same whichever EXR writer made the file.
/// `None` where the file is missing or cannot be read (cut short, corrupt).
pub fn checksum_of(path: &Path) -> Option<String> {
    image::exr_content_hash(path).ok().map(hex)
}

/// Whether the image is finished and undamaged: it reads, and its content
/// matches the checksum recorded after it was written (`expected` where the
/// manifest already holds it, else the checksum file).
pub fn verify(path: &Path, expected: Option<&str>) -> bool {
    path.exists()
        && recorded(path, expected).is_some_and(|sum| checksum_of(path).as_ref() == Some(&sum))
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

/// Writes `bytes` to a temporary file beside `target` and renames it into
/// place, so that no reader, and no later run after a kill, sees a partial
/// file under the final name. The temporary name holds the process id and
/// the time, so that shards on different nodes of a shared filesystem
/// (where process ids repeat) never write into one temporary file.
pub fn write_atomically(target: &Path, bytes: &[u8]) -> Result<()> {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let mut name = std::ffi::OsString::from(".");
    name.push(target.file_name().unwrap_or_default());
    name.push(format!(".{}.{nanos}.partial", std::process::id()));
    let tmp = target.with_file_name(name);
    let result = fs::write(&tmp, bytes)
        .and_then(|()| fs::rename(&tmp, target))
        .with_context(|| format!("writing {}", target.display()));
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}
