//! An experiment's output folder, written under `<out>.partial` and renamed
//! to `<out>` only when complete: a folder named `<out>` always holds a
//! finished experiment. Cached references and bakes survive reruns and
//! failures.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use crate::output::{check_only, entries, Contents};

/// The folder of cached references inside an output folder.
pub const REFERENCE_DIR: &str = "reference";

/// The folder of cached bakes (base images per quality) inside an output
/// folder.
pub const BAKES_DIR: &str = "bakes";

/// Folders of an output folder that are kept from run to run.
const CACHES: &[&str] = &[REFERENCE_DIR, BAKES_DIR];

/// Files an experiment writes besides PNG images and the cache folders.
const FILES: &[&str] = &["table.md", "frames.csv", "convergence.csv", "qualities.csv"];

/// An output folder being written.
pub struct Staging {
    out: PathBuf,
    partial: PathBuf,
}

impl Staging {
    /// Prepares `<out>.partial`: emptied of an earlier attempt's results,
    /// keeping (and adopting from a finished `<out>`) cached references and
    /// bakes.
    /// Refuses folders holding anything an experiment does not write, so a
    /// mistyped `--out` cannot replace unrelated files.
    pub fn begin(out: &Path) -> Result<Staging> {
        let name = out
            .file_name()
            .with_context(|| format!("--out {}: names no folder", out.display()))?;
        let mut partial_name = name.to_os_string();
        partial_name.push(".partial");
        let partial = out.with_file_name(partial_name);
        check_ours(out)?;
        check_ours(&partial)?;
        if partial.exists() {
            for entry in entries(&partial)? {
                if !is_cache(&entry) {
                    std::fs::remove_file(&entry)
                        .with_context(|| format!("removing {}", entry.display()))?;
                }
            }
        }
        let refs = partial.join(REFERENCE_DIR);
        std::fs::create_dir_all(&refs).with_context(|| format!("creating {}", refs.display()))?;
        for cache in CACHES {
            let old = out.join(cache);
            if old.is_dir() {
                let dir = partial.join(cache);
                std::fs::create_dir_all(&dir)
                    .with_context(|| format!("creating {}", dir.display()))?;
                for entry in entries(&old)? {
                    let to = dir.join(entry.file_name().expect("directory entries have names"));
                    if !to.exists() {
                        std::fs::rename(&entry, &to).with_context(|| {
                            format!("moving {} to {}", entry.display(), to.display())
                        })?;
                    }
                }
            }
        }
        Ok(Staging {
            out: out.into(),
            partial,
        })
    }

    /// Where results are written until [`Staging::finish`].
    pub fn dir(&self) -> &Path {
        &self.partial
    }

    /// Replaces `<out>` (an earlier experiment's output) with the finished
    /// results.
    pub fn finish(self) -> Result<PathBuf> {
        if self.out.exists() {
            check_ours(&self.out)?;
            std::fs::remove_dir_all(&self.out)
                .with_context(|| format!("removing the earlier {}", self.out.display()))?;
        }
        std::fs::rename(&self.partial, &self.out).with_context(|| {
            format!(
                "renaming {} to {}",
                self.partial.display(),
                self.out.display()
            )
        })?;
        Ok(self.out)
    }
}

/// What an experiment writes into its folder: its tables and plots, and
/// the cache folders.
const CONTENTS: Contents = Contents {
    what: "an experiment",
    owns: |name, is_dir| {
        if is_dir {
            CACHES.contains(&name)
        } else {
            FILES.contains(&name) || name.ends_with(".png")
        }
    },
};

/// Fails unless `dir` is absent or holds only what an experiment writes.
fn check_ours(dir: &Path) -> Result<()> {
    check_only(dir, &CONTENTS)
}

/// Whether `entry` is one of the cache folders.
fn is_cache(entry: &Path) -> bool {
    entry.is_dir()
        && entry
            .file_name()
            .is_some_and(|n| CACHES.iter().any(|c| n == *c))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_appears_only_when_finished_and_references_survive() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("exp");
        let s = Staging::begin(&out).unwrap();
        std::fs::write(s.dir().join("table.md"), "one").unwrap();
        std::fs::write(s.dir().join(REFERENCE_DIR).join("a.exr"), "ref").unwrap();
        let bake = s.dir().join(BAKES_DIR).join("q0.3");
        std::fs::create_dir_all(&bake).unwrap();
        std::fs::write(bake.join("manifest.json"), "{}").unwrap();
        assert!(!out.exists());
        assert_eq!(s.finish().unwrap(), out);
        assert!(!root.path().join("exp.partial").exists());

        // A second run that fails leaves the first output untouched; a
        // third adopts the cached reference and replaces the results.
        let s = Staging::begin(&out).unwrap();
        assert!(s.dir().join(REFERENCE_DIR).join("a.exr").exists());
        assert!(s
            .dir()
            .join(BAKES_DIR)
            .join("q0.3")
            .join("manifest.json")
            .exists());
        assert!(!s.dir().join("table.md").exists());
        drop(s);
        assert_eq!(
            std::fs::read_to_string(out.join("table.md")).unwrap(),
            "one"
        );
        let s = Staging::begin(&out).unwrap();
        std::fs::write(s.dir().join("table.md"), "two").unwrap();
        s.finish().unwrap();
        assert_eq!(
            std::fs::read_to_string(out.join("table.md")).unwrap(),
            "two"
        );
        assert!(out.join(REFERENCE_DIR).join("a.exr").exists());
        assert!(out.join(BAKES_DIR).join("q0.3").is_dir());
    }

    #[test]
    fn foreign_folders_are_not_replaced() {
        let root = tempfile::tempdir().unwrap();
        std::fs::write(root.path().join("notes.txt"), "mine").unwrap();
        let e = Staging::begin(root.path()).err().unwrap().to_string();
        assert!(e.contains("notes.txt") && e.contains("refusing"), "{e}");
        let file = root.path().join("notes.txt");
        assert!(Staging::begin(&file).is_err());
    }
}
