//! `rangewalk compare`: the error of range images against a reference.

use std::path::PathBuf;

use anyhow::{Context, Result};
use rangewalk::eval::metrics;
use rangewalk::image;

/// `rangewalk compare`.
#[derive(clap::Args)]
pub struct CompareArgs {
    reference: PathBuf,
    #[arg(required = true)]
    images: Vec<PathBuf>,
}

pub fn run(args: CompareArgs) -> Result<()> {
    let CompareArgs { reference, images } = args;
    let r = image::read_exr(&reference)?;
    // The scene's size for telling one camera position from another.
    let scale = r.distance.iter().copied().fold(0.0, f32::max);
    for p in images {
        let t = image::read_exr(&p)?;
        let against = || format!("{} against {}", p.display(), reference.display());
        let e = metrics::check_same_view(&t.meta, &r.meta, scale)
            .and_then(|()| metrics::compare(&t, &r, None))
            .with_context(against)?;
        if let Some(w) = metrics::time_warning(&t.meta, &r.meta) {
            eprintln!("warning: {}: {w}", against());
        }
        println!(
            "{}: LRMS {:.4}, bias {:+.4}, 8x8-block LRMS {:.4}, block p99 {:.4} over {} pixels",
            p.display(),
            e.lrms,
            e.bias,
            e.block_lrms,
            e.block_p99,
            e.pixels
        );
    }
    Ok(())
}
