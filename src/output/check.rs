//! Output paths checked before the work that fills them starts: a render
//! that runs to the end and only then finds its folder missing, or writes
//! an EXR under a `.txt` name, loses the work or misleads. A file's folder
//! must exist; an output folder may be new, with its parents, but its
//! nearest existing ancestor must be a folder files can be created in.
//! Nothing is written into a bake: a frame saved over a base image ruins
//! the bake it was made from.

use std::path::{Path, PathBuf};

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

/// Checks that `path` (given with `flag`) names a file of `kind` (by its
/// extension), outside any bake, that can be created in its folder.
pub fn check_output(flag: &str, path: &Path, kind: OutputKind) -> Result<()> {
    if path.is_dir() {
        bail!(
            "{flag} {}: is a folder; give the name of a file to write in it",
            path.display()
        );
    }
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
        match dir.try_exists() {
            Ok(true) => bail!(
                "{flag} {}: {} is a file, not a folder",
                path.display(),
                dir.display()
            ),
            _ => bail!(
                "{flag} {}: the folder {} does not exist",
                path.display(),
                dir.display()
            ),
        }
    }
    check_outside_stores(flag, path, dir)?;
    check_writable(flag, path, dir)
}

/// Checks that the folder `path` (given with `flag`) can be written: it
/// is a folder files can be created in, or it does not exist yet and its
/// nearest existing ancestor is a folder it can be created in (commands
/// make output folders with their parents, as `mkdir -p`, so that
/// `--out out/run` works in a fresh checkout). Either way it must not lie
/// inside a bake.
pub fn check_output_dir(flag: &str, path: &Path) -> Result<()> {
    if path.exists() {
        if !path.is_dir() {
            bail!("{flag} {}: exists and is not a folder", path.display());
        }
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            check_outside_stores(flag, path, parent)?;
        }
        return check_writable(flag, path, path);
    }
    let mut ancestor = path.parent();
    while let Some(d) = ancestor {
        if d.as_os_str().is_empty() {
            break;
        }
        if d.exists() {
            if !d.is_dir() {
                bail!(
                    "{flag} {}: {} is a file, not a folder",
                    path.display(),
                    d.display()
                );
            }
            check_outside_stores(flag, path, d)?;
            return check_writable(flag, path, d);
        }
        ancestor = d.parent();
    }
    check_outside_stores(flag, path, Path::new("."))?;
    check_writable(flag, path, Path::new("."))
}

/// Fails if `folder` (where `path` would be written) or a folder above it
/// is a bake or a radiosity store: their files are read back against the
/// plan and checksums in their manifests, and a file written over or among
/// them damages the store. Such a folder holds a manifest
/// (`manifest.json` or `manifest.toml`) whose `format` is rangewalk's.
fn check_outside_stores(flag: &str, path: &Path, folder: &Path) -> Result<()> {
    let folder = folder
        .canonicalize()
        .with_context(|| format!("{flag} {}: reading {}", path.display(), folder.display()))?;
    for dir in folder.ancestors() {
        if let Some(manifest) = store_manifest(dir) {
            bail!(
                "{flag} {}: would be written into the rangewalk store {} (it holds {}), \
                 which only its own command writes; choose a path outside it",
                path.display(),
                dir.display(),
                manifest.display()
            );
        }
    }
    Ok(())
}

/// The manifest that makes `dir` a bake or radiosity store, if it is one.
fn store_manifest(dir: &Path) -> Option<PathBuf> {
    let format = |file: &Path| -> Option<String> {
        let text = std::fs::read_to_string(file).ok()?;
        let format = if file.extension()? == "json" {
            serde_json::from_str::<serde_json::Value>(&text)
                .ok()?
                .get("format")?
                .as_str()?
                .to_string()
        } else {
            toml::from_str::<toml::Table>(&text)
                .ok()?
                .get("format")?
                .as_str()?
                .to_string()
        };
        Some(format)
    };
    ["manifest.json", "manifest.toml"]
        .into_iter()
        .map(|name| dir.join(name))
        .find(|file| format(file).is_some_and(|f| f.starts_with("rangewalk-")))
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
        assert!(e.to_string().contains("is a file, not a folder"), "{e}");
        let e = check_output("--out", &file.join("a.exr"), OutputKind::Exr).unwrap_err();
        assert!(e.to_string().contains("is a file, not a folder"), "{e}");
        let e = check_output("--out", &new.join("a.exr"), OutputKind::Exr).unwrap_err();
        assert!(e.to_string().contains("does not exist"), "{e}");
        let e = check_output_dir("--out", Path::new("/proc/rangewalk/deeper")).unwrap_err();
        assert!(
            format!("{e:#}").contains("cannot create files in /proc"),
            "{e:#}"
        );
        let e = check_output("--out", d.path(), OutputKind::Json).unwrap_err();
        assert!(e.to_string().contains("is a folder"), "{e}");
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

    #[test]
    fn nothing_is_written_into_a_bake_or_radiosity_store() {
        let d = tempfile::tempdir().unwrap();
        let bake = d.path().join("bake");
        let images = bake.join("images");
        let radiosity = bake.join("radiosity");
        std::fs::create_dir_all(&images).unwrap();
        std::fs::create_dir_all(&radiosity).unwrap();
        std::fs::write(
            bake.join("manifest.json"),
            r#"{"format": "rangewalk-base-images", "version": 2}"#,
        )
        .unwrap();
        std::fs::write(
            radiosity.join("manifest.toml"),
            "format = \"rangewalk-bake\"\n",
        )
        .unwrap();
        for file in [
            bake.join("images/base-0-0.exr"),
            bake.join("frame.exr"),
            radiosity.join("x.exr"),
        ] {
            let e = check_output("--out", &file, OutputKind::Exr).unwrap_err();
            assert!(e.to_string().contains("rangewalk store"), "{e}");
        }
        let e = check_output("--out", &bake.join("plan.json"), OutputKind::Json).unwrap_err();
        assert!(e.to_string().contains("manifest.json"), "{e}");
        for folder in [
            bake.join("walk"),
            images.join("new/deeper"),
            radiosity.clone(),
        ] {
            let e = check_output_dir("--out", &folder).unwrap_err();
            assert!(e.to_string().contains("rangewalk store"), "{e}");
        }
        // The store itself may be named (a bake resumed, a store replaced
        // by its own command), and so may a path beside it.
        check_output_dir("--out", &bake).unwrap();
        check_output("--out", &d.path().join("frame.exr"), OutputKind::Exr).unwrap();
        // A folder merely holding some other manifest is not a store.
        let other = d.path().join("other");
        std::fs::create_dir(&other).unwrap();
        std::fs::write(other.join("manifest.json"), r#"{"format": "npm"}"#).unwrap();
        check_output("--out", &other.join("a.exr"), OutputKind::Exr).unwrap();
    }
}
