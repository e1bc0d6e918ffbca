//! Output paths checked before the work that fills them starts: a render
//! that runs to the end and only then finds its folder missing, or writes
//! an EXR under a `.txt` name, loses the work or misleads.

use std::path::Path;

use anyhow::{bail, Context, Result};

/// The kinds of image file a command writes, by extension.
#[derive(Clone, Copy, Debug)]
pub enum OutputKind {
    Exr,
    Png,
    Hdr,
}

impl OutputKind {
    fn extensions(self) -> &'static [&'static str] {
        match self {
            OutputKind::Exr => &["exr"],
            OutputKind::Png => &["png"],
            OutputKind::Hdr => &["hdr", "pic", "rgbe"],
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
