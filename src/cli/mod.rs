//! The command line's arguments, parsed with clap and turned into the
//! library's settings: the library itself knows nothing of clap.

pub mod bake;
pub mod bake_options;
pub mod bake_status;
pub mod camera;
pub mod compare;
pub mod experiment;
pub mod export;
pub mod info;
pub mod plan;
pub mod radiosity;
pub mod render;
pub mod slurm;
pub mod synth;
pub mod view;

use std::path::Path;
use std::str::FromStr;

use anyhow::{Context, Result};
use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use rangewalk::accel::{self, Backend, InstancedEngine};
use rangewalk::scene::Scene;
use strum::{EnumMessage, VariantArray};

/// The flag of a settings field: `light_rays` is `--light-rays`.
pub fn flag(field: &str) -> String {
    format!("--{}", field.replace('_', "-"))
}

/// The parser of one of the library's closed sets: each value's name and
/// doc line listed in `--help`, the text parsed by the enum's own
/// `FromStr`, so that the names are written once, on the enum.
pub fn choice<T>() -> impl TypedValueParser<Value = T>
where
    T: VariantArray + EnumMessage + FromStr + Into<&'static str> + Copy + Send + Sync,
    T: 'static,
{
    let values = T::VARIANTS.iter().map(|&v| {
        let value = PossibleValue::new(v.into());
        match v.get_documentation() {
            // A doc comment's lines are one paragraph of help.
            Some(doc) => value.help(doc.split_whitespace().collect::<Vec<_>>().join(" ")),
            None => value,
        }
    });
    PossibleValuesParser::new(values).map(|name| match name.parse::<T>() {
        Ok(v) => v,
        Err(_) => unreachable!("`{name}` is one of the names the enum lists"),
    })
}

/// The scene in `path`, its warnings on stderr.
pub fn load(path: &Path) -> Result<Scene> {
    let scene = Scene::load(path)?;
    if scene.dropped_triangles > 0 {
        eprintln!(
            "warning: {}: dropped {} zero-area triangle(s)",
            path.display(),
            scene.dropped_triangles
        );
    }
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    Ok(scene)
}

/// A ray engine over the scene posed at the animation's start.
pub fn engine_at_start(s: &Scene, backend: Backend) -> Result<Box<dyn InstancedEngine>> {
    accel::build(backend, &s.geometry(), &s.at(s.animation.start))
        .with_context(|| format!("building the {backend} ray engine"))
}
