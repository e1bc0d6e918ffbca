//! How much of a bake's base pixels see geometry: over the whole
//! projections (what a whole bake stores) and over the pixels the images
//! hold (their windows), with the bytes of the image files:
//!
//! ```sh
//! cargo run --release --example base_coverage -- <bake-dir>
//! ```

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use rangewalk::bake::Manifest;
use rangewalk::image::{self, NO_HIT};

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [dir] = &args[..] else {
        bail!("usage: base_coverage <bake-dir>");
    };
    let dir = PathBuf::from(dir);
    let m = Manifest::read(&dir)?;
    let (mut seen, mut held, mut whole, mut bytes) = (0u64, 0u64, 0u64, 0u64);
    for e in &m.images {
        let path = dir.join(&e.file);
        let img = image::read_exr(&path).with_context(|| format!("{}", path.display()))?;
        let (fw, fh) = img.meta.camera.full_size();
        seen += img.object_id.iter().filter(|&&o| o != NO_HIT).count() as u64;
        held += img.len() as u64;
        whole += u64::from(fw) * u64::from(fh);
        bytes += std::fs::metadata(&path)?.len();
    }
    let pct = |a: u64, b: u64| 100.0 * a as f64 / b.max(1) as f64;
    println!(
        "{} images of {}²: pixels that see geometry: {:.2}% of the whole projections, \
         {:.2}% of the {:.2}% of them the images hold; image files {:.1} MB",
        m.images.len(),
        m.settings.size,
        pct(seen, whole),
        pct(seen, held),
        pct(held, whole),
        bytes as f64 / 1e6
    );
    Ok(())
}
