//! `rangewalk bake --status` and `--finish`: watching and sealing a bake
//! that may run anywhere.

use std::path::Path;

use anyhow::{bail, Result};
use rangewalk::bake;

/// The first few of `files`, for a message.
fn some_of(files: &[String]) -> String {
    const SHOWN: usize = 8;
    let mut s = files
        .iter()
        .take(SHOWN)
        .cloned()
        .collect::<Vec<_>>()
        .join(", ");
    if files.len() > SHOWN {
        s += &format!(" and {} more", files.len() - SHOWN);
    }
    s
}

/// `rangewalk bake --status`: how many images are done, who is working
/// on them, and what to do next. Takes no lock: it watches a bake that
/// may run anywhere.
pub fn status(dir: &Path) -> Result<()> {
    let st = bake::status::status(dir)?;
    let radiosity = match st.radiosity {
        None => "",
        Some(true) => "; radiosity solved",
        Some(false) => "; radiosity not solved yet",
    };
    let missing = st.total - st.done;
    let verdict = if st.complete {
        "bake complete".to_string()
    } else if st.sealed {
        format!(
            "not complete: {missing} of its images went missing after the bake was completed; run the bake command again to render them again"
        )
    } else if missing == 0 && st.running.is_empty() {
        format!(
            "not complete: every image is done but not checked yet; run `rangewalk bake --finish {}` (or the bake command again)",
            dir.display()
        )
    } else {
        "not complete".to_string()
    };
    println!(
        "{}: {} of {} images done ({:.0}%){radiosity}; {verdict}",
        dir.display(),
        st.done,
        st.total,
        100.0 * st.done as f64 / st.total.max(1) as f64,
    );
    if !st.missing.is_empty() {
        println!("  to do: {}", some_of(&st.missing));
    }
    if let Some(noise) = &st.noise {
        println!("  noise of the done images: {noise}");
    }
    for h in &st.running {
        println!("  running: {h}");
    }
    Ok(())
}

/// `rangewalk bake --finish`: every image checked, the bake sealed.
pub fn finish(dir: &Path) -> Result<()> {
    let st = bake::status::finish(dir)?;
    if st.removed > 0 {
        println!(
            "removed {} temporary files left by a stopped run",
            st.removed
        );
    }
    if !st.missing.is_empty() {
        bail!(
            "{}: {} of {} images missing or damaged: {}; run their shards again (or the same bake or slurm command), then finish again",
            dir.display(),
            st.missing.len(),
            st.total,
            some_of(&st.missing)
        );
    }
    println!(
        "bake complete: {}: {} images read back against their checksums",
        dir.display(),
        st.total
    );
    Ok(())
}
