//! Output paths checked before the work that fills them starts: a render
//! that runs to the end and only then finds its folder missing, or writes
//! an EXR under a `.txt` name, loses the work or misleads. Output folders
//! are held to the same rule: the folder may be new, but the one it goes
//! in must exist, so that a mistyped parent is an error, not a tree of
//! folders made by the command.

use std::path::Path;

use anyhow::{bail, Context, Result};

/// The kinds of image file a command writes, by extension.
#[derive(Clone, Copy, Debug)]
pub enum OutputKind {
    Exr,
    Png,
    Hdr,
    Json,
}

impl OutputKind {
    fn extensions(self) -> &'static [&'static str] {
        match self {
            OutputKind::Exr => &["exr"],
            OutputKind::Png => &["png"],
            OutputKind::Hdr => &["hdr", "pic", "rgbe"],
            OutputKind::Json => &["json"],
        }
    }
}

/// Checks that `path` (given with `flag`) has an extension of `kind` and
/// that a file can be created in its folder, by creating and removing one.
pub fn check_output(flag: &str, path: &Path, kind: OutputKind) -> Result<()> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let wanted = kind.extensions();
    if !wanted.contains(&ext.as_str()) {
        bail!(
            "{flag} {}: the extension `.{ext}` is not one this writes (expected .{})",
            path.display(),
            wanted.join(" or .")
        );
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        bail!(
            "{flag} {}: the folder {} does not exist",
            path.display(),
            dir.display()
        );
    }
    if path.is_dir() {
        bail!("{flag} {}: is a folder, not a file", path.display());
    }
    check_writable(flag, path, dir)
}

/// Checks that the folder `path` (given with `flag`) can be written: it
/// is a folder files can be created in, or it does not exist yet and its
/// nearest existing ancestor is a folder it can be created in (commands
/// make output folders with their parents, as `mkdir -p`, so that
/// `--out out/run` works in a fresh checkout).
pub fn check_output_dir(flag: &str, path: &Path) -> Result<()> {
    if path.exists() {
        if !path.is_dir() {
            bail!("{flag} {}: exists and is not a folder", path.display());
        }
        return check_writable(flag, path, path);
    }
    let mut ancestor = path.parent();
    while let Some(d) = ancestor {
        if d.as_os_str().is_empty() {
            return check_writable(flag, path, Path::new("."));
        }
        if d.exists() {
            if !d.is_dir() {
                bail!("{flag} {}: {} is not a folder", path.display(), d.display());
            }
            return check_writable(flag, path, d);
        }
        ancestor = d.parent();
    }
    check_writable(flag, path, Path::new("."))
}

/// Whether a file can be created in `dir`, found by creating and removing
/// one: permissions alone do not tell (read-only mounts, quotas, ACLs).
fn check_writable(flag: &str, path: &Path, dir: &Path) -> Result<()> {
    let probe = dir.join(format!(".rangewalk-probe-{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .with_context(|| {
            format!(
                "{flag} {}: cannot create files in {}",
                path.display(),
                dir.display()
            )
        })?;
    // Best effort: the probe is empty and hidden; failing to remove it
    // harms nothing the command writes.
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folders_are_checked_like_files() {
        let d = tempfile::tempdir().unwrap();
        let new = d.path().join("new");
        check_output_dir("--out", &new).unwrap();
        assert!(!new.exists(), "the check created the folder");
        check_output_dir("--out", d.path()).unwrap();
        // Missing parents are made with the folder, as `mkdir -p`.
        check_output_dir("--out", &new.join("deeper")).unwrap();
        assert!(!new.exists(), "the check created a parent");
        let file = d.path().join("f");
        std::fs::write(&file, "").unwrap();
        let e = check_output_dir("--out", &file).unwrap_err();
        assert!(e.to_string().contains("not a folder"), "{e}");
        let e = check_output_dir("--out", &file.join("under")).unwrap_err();
        assert!(e.to_string().contains("is not a folder"), "{e}");
        let e = check_output_dir("--out", Path::new("/proc/rangewalk/deeper")).unwrap_err();
        assert!(
            format!("{e:#}").contains("cannot create files in /proc"),
            "{e:#}"
        );
        let e = check_output("--out", d.path(), OutputKind::Json).unwrap_err();
        assert!(e.to_string().contains("`.`"), "{e}");
        let e = check_output("--out", &d.path().join("p.txt"), OutputKind::Json).unwrap_err();
        assert!(e.to_string().contains("expected .json"), "{e}");
        // A place no one can create files in, even root.
        let e = check_output_dir("--out", Path::new("/proc/rangewalk")).unwrap_err();
        assert!(
            format!("{e:#}").contains("cannot create files in /proc"),
            "{e:#}"
        );
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 1);
    }
}
