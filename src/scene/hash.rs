//! Content hashes of a scene, so that work stored on disk (reference
//! renders, bakes) is only reused for the scene it was made from, and a
//! mismatch can say what changed.

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};

use super::{Bsdf, Scene};
use crate::checksum::{fnv1a64, hex, Fnv};

/// Hashes of the parts of a scene that change what is rendered: the scene
/// file's text (lights, motion, cameras, view space), every object's mesh
/// and every material with its texture's texels (materials may come from
/// MTL files the text only names).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ContentHash {
    /// All of the below in one.
    pub total: String,
    /// The scene file's bytes.
    pub text: String,
    /// Per object, in order: name and hash of its positions, triangles and
    /// texture coordinates.
    pub meshes: Vec<(String, String)>,
    /// Per material, in order: name and hash of its parameters and texels.
    pub materials: Vec<(String, String)>,
}

impl ContentHash {
    pub fn of(scene: &Scene) -> Result<ContentHash> {
        let text = std::fs::read(&scene.source)
            .with_context(|| format!("reading {}", scene.source.display()))?;
        let mut total = Fnv::default();
        total.write(&text);
        let meshes: Vec<(String, String)> = scene
            .objects
            .iter()
            .map(|o| {
                let mut h = Fnv::default();
                h.floats(o.mesh.positions.iter().flat_map(|p| p.to_array()));
                for t in &o.mesh.triangles {
                    for v in t {
                        h.write(&v.to_le_bytes());
                    }
                }
                if let Some(uvs) = &o.mesh.uvs {
                    h.floats(uvs.iter().flat_map(|p| p.to_array()));
                }
                total.write(&h.finish().to_le_bytes());
                (o.name.clone(), h.hex())
            })
            .collect();
        let materials: Vec<(String, String)> = scene
            .materials
            .iter()
            .map(|m| {
                let mut h = Fnv::default();
                h.write(format!("{:?}", m.emission).as_bytes());
                match &m.bsdf {
                    Bsdf::Diffuse {
                        reflectance,
                        texture,
                    } => {
                        h.floats(reflectance.to_array());
                        if let Some(t) = texture {
                            h.write(&t.width.to_le_bytes());
                            h.write(&t.height.to_le_bytes());
                            h.floats(t.texels.iter().flat_map(|c| c.to_array()));
                        }
                    }
                    other => h.write(format!("{other:?}").as_bytes()),
                }
                total.write(&h.finish().to_le_bytes());
                (m.name.clone(), h.hex())
            })
            .collect();
        Ok(ContentHash {
            total: total.hex(),
            text: hex(fnv1a64(&text)),
            meshes,
            materials,
        })
    }

    /// What differs from `other`, in words; empty when nothing does.
    pub fn differences(&self, other: &ContentHash) -> Vec<String> {
        let mut out = Vec::new();
        if self.text != other.text {
            out.push("the scene file's text".to_string());
        }
        list_differences("object", &self.meshes, &other.meshes, &mut out);
        list_differences("material", &self.materials, &other.materials, &mut out);
        if out.is_empty() && self.total != other.total {
            out.push("the scene's content".to_string());
        }
        out
    }
}

fn list_differences(
    what: &str,
    a: &[(String, String)],
    b: &[(String, String)],
    out: &mut Vec<String>,
) {
    for (name, hash) in a {
        match b.iter().find(|(n, _)| n == name) {
            None => out.push(format!("{what} `{name}` is gone")),
            Some((_, h)) if h != hash => out.push(format!("{what} `{name}` changed")),
            Some(_) => {}
        }
    }
    for (name, _) in b {
        if !a.iter().any(|(n, _)| n == name) {
            out.push(format!("{what} `{name}` is new"));
        }
    }
    let names = |v: &[(String, String)]| v.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
    if out.is_empty() && names(a) != names(b) {
        out.push(format!("the order of the {what}s"));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv_matches_the_published_vectors() {
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
    }
}
