//! How far a bake is, seen from its directory alone: for watching a bake
//! that runs elsewhere (as Slurm array tasks on other nodes), and for the
//! last step of a distributed bake, which checks every image and marks the
//! bake complete.

use std::path::Path;

use anyhow::{bail, Result};
use rayon::prelude::*;

use super::lock::{self, Holder};
use super::manifest::{self, Manifest, RADIOSITY};
use super::{sampling, Shard};
use crate::radiosity::store as radiosity_store;
use crate::render::noise::NoiseReport;

/// What a bake directory holds now.
#[derive(Clone, Debug, PartialEq)]
pub struct Status {
    /// Images of the whole bake.
    pub total: usize,
    /// Images written with their checksum recorded (not read back).
    pub done: usize,
    /// Whether the manifest marks the bake complete (every image was read
    /// back against its checksum once).
    pub sealed: bool,
    /// Sealed, and no image has gone missing since: what readers need.
    pub complete: bool,
    /// Whether the radiosity stage is solved; `None` where the images
    /// trace indirect light and need none.
    pub radiosity: Option<bool>,
    /// Files of the images not done yet, in manifest order.
    pub missing: Vec<String>,
    /// The runs working on the bake now (rendering, finishing).
    pub running: Vec<Holder>,
    /// Temporary files of stopped runs removed (by `finish`).
    pub removed: usize,
    /// The noise the done images reached, together (images of a
    /// rangewalk before manifest version 4 have no report).
    pub noise: Option<NoiseReport>,
}

/// Counts the done images of the bake in `dir` from what is on disk,
/// cheaply: an image counts when its file and its checksum exist.
pub fn status(dir: &Path) -> Result<Status> {
    if !dir.join(manifest::MANIFEST).exists() {
        bail!(
            "{} holds no bake yet (no {}): it is made by the first job (`rangewalk bake --prepare`) or the first run of the bake",
            dir.display(),
            manifest::MANIFEST
        );
    }
    let m = Manifest::read(dir)?;
    let missing: Vec<String> = m
        .images
        .iter()
        .filter(|e| !is_done(dir, &m, e))
        .map(|e| e.file.clone())
        .collect();
    Ok(Status {
        total: m.images.len(),
        done: m.images.len() - missing.len(),
        sealed: m.complete,
        complete: m.complete && missing.is_empty(),
        radiosity: radiosity_solved(dir, &m),
        noise: noise(dir, &m, &missing),
        missing,
        running: lock::running(dir),
        removed: 0,
    })
}

/// Reads every image of the bake in `dir` back against its recorded
/// checksum and, when none is missing or damaged, records the checksums in
/// the manifest and marks the bake complete. Returns the status after it;
/// its `missing` lists the images missing or damaged.
///
/// Refused while a run renders any image: its images are not all there,
/// and reading them all is the long part. Registered as working on every
/// image meanwhile, so no run starts rendering under it; alone, it removes
/// what stopped runs left (the last job of a Slurm bake runs after every
/// task, killed ones included).
pub fn finish(dir: &Path) -> Result<Status> {
    Manifest::read(dir)?;
    let me = Holder::me("finishing", Shard::ALL);
    let (mut m, removed, _running) = {
        let setup = lock::Setup::acquire(dir, &me)?;
        let m = Manifest::read(dir)?;
        // Working on every image, it is alone once registered.
        let running = setup.register(&me)?;
        (m, setup.remove_temporaries()?, running)
    };
    let unchecked = vec![false; m.images.len()];
    let bad = seal(dir, &mut m, &unchecked)?;
    Ok(Status {
        total: m.images.len(),
        done: m.images.len() - bad.len(),
        sealed: m.complete,
        complete: m.complete && bad.is_empty(),
        radiosity: radiosity_solved(dir, &m),
        noise: noise(dir, &m, &bad),
        missing: bad,
        running: Vec::new(),
        removed,
    })
}

/// The reports of the images not `missing`, from the manifest where it
/// holds them, else from beside the images.
fn noise(dir: &Path, m: &Manifest, missing: &[String]) -> Option<NoiseReport> {
    let missing: std::collections::HashSet<&String> = missing.iter().collect();
    let reports: Vec<NoiseReport> = m
        .images
        .iter()
        .filter(|e| !missing.contains(&e.file))
        .filter_map(|e| {
            e.noise
                .or_else(|| sampling::read_report(&dir.join(&e.file)))
        })
        .collect();
    NoiseReport::combine(&reports)
}

fn radiosity_solved(dir: &Path, m: &Manifest) -> Option<bool> {
    m.settings
        .indirect
        .uses_records()
        .then(|| dir.join(RADIOSITY).join(radiosity_store::MANIFEST).exists())
}

/// How many images of `m` are done (as [`status`] counts them).
pub(super) fn done(dir: &Path, m: &Manifest) -> usize {
    m.images.iter().filter(|e| is_done(dir, m, e)).count()
}

fn is_done(dir: &Path, m: &Manifest, e: &manifest::ImageEntry) -> bool {
    let path = dir.join(&e.file);
    path.exists()
        && (!m.has_planes() || manifest::planes_path(&path).exists())
        && manifest::recorded(&path, e.fnv1a64.as_deref()).is_some()
}

/// Verifies the images not marked in `checked` and, when every image is
/// finished and undamaged, records the checksums in the manifest and marks
/// it complete (written atomically). Returns the files missing or damaged.
pub(super) fn seal(dir: &Path, m: &mut Manifest, checked: &[bool]) -> Result<Vec<String>> {
    let recorded: Vec<Option<String>> = m
        .images
        .iter()
        .map(|e| manifest::recorded(&dir.join(&e.file), e.fnv1a64.as_deref()))
        .collect();
    let planes = m.has_planes();
    // Reading images back is the finishing job's whole work: on all its
    // cores.
    let bad: Vec<String> = m
        .images
        .par_iter()
        .zip(&recorded)
        .zip(checked)
        .filter(|((e, sum), &ok)| {
            sum.is_none() || (!ok && !manifest::verify(&dir.join(&e.file), sum.as_deref(), planes))
        })
        .map(|((e, _), _)| e.file.clone())
        .collect();
    if bad.is_empty() && !m.complete {
        for (e, sum) in m.images.iter_mut().zip(recorded) {
            e.fnv1a64 = sum;
            e.noise = sampling::read_report(&dir.join(&e.file));
        }
        m.complete = true;
        m.write(dir)?;
    }
    Ok(bad)
}
