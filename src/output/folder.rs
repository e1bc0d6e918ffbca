//! Output folders a command writes whole. A folder is made as
//! `<out>.partial` and renamed to `<out>` when complete, so a folder named
//! `<out>` always holds a finished result; a failure removes the partial
//! folder. An existing `<out>` is replaced only while it holds nothing but
//! what the command writes: a mistyped `--out` naming the user's folder,
//! the bake being read or the scene's folder is refused, never emptied.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use super::file::temporary_for;

/// What a command writes into a folder of its own, by entry name.
#[derive(Clone, Copy)]
pub struct Contents {
    /// The command's result as a message names it ("a walk").
    pub what: &'static str,
    /// Whether an entry so named (a folder when `is_dir`) is the command's.
    pub owns: fn(name: &str, is_dir: bool) -> bool,
}

impl Contents {
    /// Whether `entry` (a file or folder in an output folder; symbolic
    /// links are never the command's) was written by the command, or is
    /// the temporary of such a file left by a killed run.
    fn owns_entry(&self, entry: &Path) -> Result<bool> {
        let kind = std::fs::symlink_metadata(entry)
            .with_context(|| format!("reading {}", entry.display()))?
            .file_type();
        let Some(name) = entry.file_name().and_then(|n| n.to_str()) else {
            return Ok(false);
        };
        Ok(if kind.is_dir() {
            (self.owns)(name, true)
        } else if kind.is_file() {
            (self.owns)(name, false) || temporary_for(name).is_some_and(|t| (self.owns)(t, false))
        } else {
            false
        })
    }
}

/// Whether `name` is `<prefix><digits>.<ext>` for one of `exts`, as the
/// numbered files of an output folder are (`frame-0007.exr`).
pub fn numbered(name: &str, prefix: &str, exts: &[&str]) -> bool {
    let Some((stem, ext)) = name.rsplit_once('.') else {
        return false;
    };
    let digits = stem.strip_prefix(prefix).unwrap_or_default();
    exts.contains(&ext) && !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())
}

/// Fails unless `dir` is absent or a folder holding only what `contents`
/// owns.
pub fn check_only(dir: &Path, contents: &Contents) -> Result<()> {
    let meta = match std::fs::symlink_metadata(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        m => m.with_context(|| format!("reading {}", dir.display()))?,
    };
    if meta.file_type().is_symlink() {
        bail!(
            "{} is a symbolic link; {} replaces only a folder it wrote: choose another folder",
            dir.display(),
            contents.what
        );
    }
    if !meta.is_dir() {
        bail!(
            "{} exists and is not a folder; choose another folder",
            dir.display()
        );
    }
    for entry in entries(dir)? {
        if !contents.owns_entry(&entry)? {
            bail!(
                "refusing to replace {}: it holds {}, which {} does not write; \
                 choose another folder, or move what it holds",
                dir.display(),
                entry.display(),
                contents.what
            );
        }
    }
    Ok(())
}

/// An output folder being written.
pub struct Folder {
    out: PathBuf,
    partial: PathBuf,
    contents: Contents,
    finished: bool,
}

impl Folder {
    /// Checks `out` and `<out>.partial` (either may hold an earlier run's
    /// result, and nothing else) and starts an empty `<out>.partial`.
    pub fn begin(out: &Path, contents: Contents) -> Result<Folder> {
        let name = out
            .file_name()
            .with_context(|| format!("{}: names no folder", out.display()))?;
        let mut partial_name = name.to_os_string();
        partial_name.push(".partial");
        let partial = out.with_file_name(partial_name);
        check_only(out, &contents)?;
        check_only(&partial, &contents)?;
        if partial.exists() {
            empty(&partial, &contents)?;
        }
        std::fs::create_dir_all(&partial)
            .with_context(|| format!("creating {}", partial.display()))?;
        Ok(Folder {
            out: out.into(),
            partial,
            contents,
            finished: false,
        })
    }

    /// Where the result is written until [`Folder::finish`].
    pub fn path(&self) -> &Path {
        &self.partial
    }

    /// Replaces `<out>` (an earlier result) with the finished one.
    pub fn finish(mut self) -> Result<PathBuf> {
        if std::fs::symlink_metadata(&self.out).is_ok() {
            check_only(&self.out, &self.contents)?;
            empty(&self.out, &self.contents)?;
        }
        std::fs::rename(&self.partial, &self.out).with_context(|| {
            format!(
                "renaming {} to {}",
                self.partial.display(),
                self.out.display()
            )
        })?;
        self.finished = true;
        Ok(self.out.clone())
    }
}

impl Drop for Folder {
    /// An unfinished result is removed: nothing is left to be mistaken
    /// for it, or to be cleaned up by hand.
    fn drop(&mut self) {
        if !self.finished {
            let _ = empty(&self.partial, &self.contents);
        }
    }
}

/// Removes `dir`, which [`check_only`] has found to hold only what
/// `contents` owns, entry by entry: never recursively, so that anything
/// put there since the check stops the removal instead of being lost.
fn empty(dir: &Path, contents: &Contents) -> Result<()> {
    for entry in entries(dir)? {
        if !contents.owns_entry(&entry)? {
            bail!(
                "refusing to remove {}: it now holds {}, which {} does not write",
                dir.display(),
                entry.display(),
                contents.what
            );
        }
        let removed = if entry.is_dir() {
            std::fs::remove_dir(&entry)
        } else {
            std::fs::remove_file(&entry)
        };
        removed.with_context(|| format!("removing {}", entry.display()))?;
    }
    std::fs::remove_dir(dir).with_context(|| format!("removing {}", dir.display()))
}

/// The paths of `dir`'s entries, in no particular order.
pub fn entries(dir: &Path) -> Result<Vec<PathBuf>> {
    std::fs::read_dir(dir)
        .with_context(|| format!("reading {}", dir.display()))?
        .map(|e| {
            Ok(e.with_context(|| format!("reading {}", dir.display()))?
                .path())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const FRAMES: Contents = Contents {
        what: "a test",
        owns: |name, is_dir| !is_dir && name.starts_with("frame-"),
    };

    #[test]
    fn numbered_names() {
        assert!(numbered("frame-0007.exr", "frame-", &["exr", "png"]));
        assert!(numbered("mesh_12.obj", "mesh_", &["obj"]));
        for not in [
            "frame-.exr",
            "frame-7.tif",
            "frame-7a.png",
            "xframe-7.png",
            "frame-7",
        ] {
            assert!(!numbered(not, "frame-", &["exr", "png"]), "{not}");
        }
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_result_replaces_an_earlier_one_only_when_finished() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("run");
        let f = Folder::begin(&out, FRAMES).unwrap();
        std::fs::write(f.path().join("frame-1"), "one").unwrap();
        assert!(!out.exists());
        assert_eq!(f.finish().unwrap(), out);
        assert_eq!(names(root.path()), ["run"]);

        let f = Folder::begin(&out, FRAMES).unwrap();
        std::fs::write(f.path().join("frame-2"), "two").unwrap();
        drop(f);
        assert_eq!(names(root.path()), ["run"], "a failed run left its folder");
        assert_eq!(names(&out), ["frame-1"]);

        // A killed run's folder, with a temporary, is taken over.
        let partial = root.path().join("run.partial");
        std::fs::create_dir(&partial).unwrap();
        std::fs::write(partial.join(".frame-3.12.34.partial"), "").unwrap();
        let f = Folder::begin(&out, FRAMES).unwrap();
        assert!(names(f.path()).is_empty());
        std::fs::write(f.path().join("frame-3"), "three").unwrap();
        f.finish().unwrap();
        assert_eq!(names(&out), ["frame-3"]);
    }

    #[test]
    fn folders_holding_anything_else_are_refused_and_kept() {
        let root = tempfile::tempdir().unwrap();
        let mine = root.path().join("mine");
        std::fs::create_dir(&mine).unwrap();
        std::fs::write(mine.join("frame-1"), "").unwrap();
        std::fs::write(mine.join("thesis.tex"), "years").unwrap();
        std::fs::create_dir(mine.join("frame-dir")).unwrap();
        let e = Folder::begin(&mine, FRAMES).err().unwrap().to_string();
        assert!(e.contains("thesis.tex") || e.contains("frame-dir"), "{e}");
        assert!(e.contains("refusing"), "{e}");
        assert_eq!(names(&mine), ["frame-1", "frame-dir", "thesis.tex"]);

        // A partial folder is held to the same rule.
        let out = root.path().join("out");
        let partial = root.path().join("out.partial");
        std::fs::create_dir(&partial).unwrap();
        std::fs::write(partial.join("notes"), "").unwrap();
        assert!(Folder::begin(&out, FRAMES).is_err());
        assert_eq!(names(&partial), ["notes"]);

        // Something put into the output while the run worked stops the
        // replacement; it is not lost.
        let f = Folder::begin(&root.path().join("late"), FRAMES).unwrap();
        std::fs::create_dir(root.path().join("late")).unwrap();
        std::fs::write(root.path().join("late").join("frame-1"), "").unwrap();
        std::fs::write(root.path().join("late").join("mail"), "").unwrap();
        assert!(f.finish().is_err());
        assert!(root.path().join("late").join("mail").exists());

        // A file, or a link to a folder, is never the command's folder.
        let file = root.path().join("file");
        std::fs::write(&file, "").unwrap();
        assert!(check_only(&file, &FRAMES).is_err());
        let link = root.path().join("link");
        std::os::unix::fs::symlink(&mine, &link).unwrap();
        let e = check_only(&link, &FRAMES).unwrap_err().to_string();
        assert!(e.contains("symbolic link"), "{e}");
    }
}
