use std::path::PathBuf;

use anyhow::Result;

use super::Scene;

pub fn load(path: PathBuf) -> Result<Scene> {
    anyhow::bail!("{}: scene loading is not written yet", path.display())
}
