//! Materials: the `[[materials]]` of a scene file checked, and the OBJ's
//! MTL materials turned into the scene's where an object names none.

use super::*;

pub(super) fn reflectance(what: &str, field: &str, v: V3) -> Result<Vec3> {
    finite(what, field, &v)?;
    ensure!(
        v.iter().all(|&c| c >= 0.0),
        "{what}: `{field}` {v:?} has a negative channel"
    );
    ensure!(
        v.iter().all(|&c| c < 1.0),
        "{what}: `{field}` {v:?} has a channel >= 1; a reflectance must stay below 1 to conserve energy"
    );
    Ok(v.into())
}

pub(super) fn emission(what: &str, e: Option<V3>, two_sided: bool) -> Result<Option<Emission>> {
    let Some(e) = e else { return Ok(None) };
    finite(what, "emission", &e)?;
    ensure!(
        e.iter().all(|&c| c >= 0.0),
        "{what}: `emission` {e:?} has a negative channel"
    );
    Ok(Some(Emission {
        radiance: e.into(),
        two_sided,
    }))
}

pub(super) fn build_material(at: &str, m: &MaterialToml, dir: &Path) -> Result<Material> {
    Ok(match m {
        MaterialToml::Diffuse {
            name,
            reflectance: r,
            texture,
            emission: e,
            two_sided_emission,
        } => {
            let what = format!("{at}: material `{name}`");
            let reflectance = reflectance(&what, "reflectance", *r)?;
            let texture = texture
                .as_ref()
                .map(|t| read_texture(&what, "texture", &dir.join(t)))
                .transpose()?;
            if let Some(t) = &texture {
                let product = reflectance * t.largest_texel();
                ensure!(
                    product.max_element() < 1.0,
                    "{what}: `reflectance` {:?} times the largest texel of {} is {:?}, which has a channel >= 1; a reflectance must stay below 1",
                    reflectance.to_array(),
                    t.source.display(),
                    product.to_array()
                );
            }
            Material {
                name: name.clone(),
                bsdf: Bsdf::Diffuse {
                    reflectance,
                    texture,
                },
                emission: emission(&what, *e, *two_sided_emission)?,
            }
        }
        MaterialToml::Glossy {
            name,
            diffuse,
            specular,
            roughness,
            model,
            emission: e,
            two_sided_emission,
        } => {
            let what = format!("{at}: material `{name}`");
            let d = reflectance(&what, "diffuse", *diffuse)?;
            let s = reflectance(&what, "specular", *specular)?;
            let sum = d + s;
            ensure!(
                sum.max_element() < 1.0,
                "{what}: `diffuse` + `specular` = {:?} has a channel >= 1; the total reflectance must stay below 1",
                sum.to_array()
            );
            ensure!(
                roughness.is_finite() && *roughness > 0.0 && *roughness <= 1.0,
                "{what}: `roughness` {roughness} must lie in (0, 1] (use a mirror material for 0)"
            );
            let model = match model.as_str() {
                "ggx" => GlossyModel::Ggx,
                "ward" => GlossyModel::Ward,
                other => bail!(
                    "{what}: unknown glossy `model` \"{other}\" (expected \"ggx\" or \"ward\")"
                ),
            };
            Material {
                name: name.clone(),
                bsdf: Bsdf::Glossy {
                    diffuse: d,
                    specular: s,
                    roughness: *roughness,
                    model,
                },
                emission: emission(&what, *e, *two_sided_emission)?,
            }
        }
        MaterialToml::Mirror {
            name,
            reflectance: r,
        } => {
            let what = format!("{at}: material `{name}`");
            Material {
                name: name.clone(),
                bsdf: Bsdf::Mirror {
                    reflectance: reflectance(&what, "reflectance", *r)?,
                },
                emission: None,
            }
        }
    })
}

/// A texture multiplies a reflectance, so its texels only need to be
/// finite and not negative here; the product is checked where the
/// reflectance is known.
pub(super) fn read_texture(what: &str, field: &str, path: &Path) -> Result<Arc<Texture>> {
    if let Some(why) = not_a_file(path) {
        return Err(unreadable(format!(
            "{what}: `{field}` {} {why}",
            path.display()
        )));
    }
    let tex = crate::image::read_texture(path).with_context(|| format!("{what}: `{field}`"))?;
    ensure!(
        tex.texels
            .iter()
            .all(|t| t.is_finite() && t.min_element() >= 0.0),
        "{what}: texture {} has texels that are negative or not finite",
        path.display()
    );
    Ok(Arc::new(tex))
}

/// The reflectance an MTL channel of 1 or more (`Kd 1 1 1`, common in
/// files from other tools) is lowered to: the highest albedo the radiosity
/// solver is tested to converge at in a closed scene (the ρ = 0.99
/// furnace), since a reflectance of 1 would never let light go.
pub(super) const MTL_REFLECTANCE_LIMIT: f32 = 0.99;

/// The object material for an OBJ that names none (files from tools that
/// write no MTL): a mid grey.
pub(super) const DEFAULT_MATERIAL: &str = "(default diffuse)";
pub(super) const DEFAULT_REFLECTANCE: f32 = 0.5;

/// Picks the object's material: the named `[[materials]]` entry, else one
/// made from the OBJ's MTL material (Kd, map_Kd, Ke) on first use.
pub(super) fn resolve_material(
    at: &str,
    o: &ObjectToml,
    mtl_name: Option<&str>,
    obj: &ObjFile,
    materials: &mut Vec<Material>,
    warnings: &mut Vec<String>,
) -> Result<usize> {
    let known = |materials: &[Material]| {
        materials
            .iter()
            .map(|m| m.name.clone())
            .collect::<Vec<_>>()
            .join(", ")
    };
    if let Some(name) = &o.material {
        return materials
            .iter()
            .position(|m| &m.name == name)
            .ok_or_else(|| {
                anyhow!(
                    "{at}: object `{}` uses unknown material `{name}` (materials: {})",
                    o.name,
                    known(materials)
                )
            });
    }
    let Some(mtl_name) = mtl_name else {
        warnings.push(format!(
            "{at}: object `{}` has no `material` and its mesh names no MTL material (or its MTL file is missing): using a diffuse grey of reflectance {DEFAULT_REFLECTANCE}",
            o.name
        ));
        if let Some(i) = materials.iter().position(|m| m.name == DEFAULT_MATERIAL) {
            return Ok(i);
        }
        materials.push(Material {
            name: DEFAULT_MATERIAL.to_string(),
            bsdf: Bsdf::Diffuse {
                reflectance: Vec3::splat(DEFAULT_REFLECTANCE),
                texture: None,
            },
            emission: None,
        });
        return Ok(materials.len() - 1);
    };
    if let Some(i) = materials.iter().position(|m| m.name == mtl_name) {
        return Ok(i);
    }
    let mtl = obj
        .materials
        .iter()
        .find(|m| m.name == mtl_name)
        .ok_or_else(|| {
            anyhow!(
                "{at}: object `{}`: MTL material `{mtl_name}` is not defined",
                o.name
            )
        })?;
    let file = obj.mtl_files.get(mtl_name).unwrap_or(&obj.path);
    let what = format!("{}: MTL material `{mtl_name}`", file.display());
    let texture = match &mtl.diffuse_texture {
        Some(t) => {
            let path = obj.path.parent().unwrap_or(Path::new(".")).join(t);
            match not_a_file(&path) {
                None => Some(read_texture(&what, "map_Kd", &path)?),
                Some(why) => {
                    warnings.push(format!(
                        "{what}: `map_Kd` texture {} {why}: using `Kd` alone",
                        path.display()
                    ));
                    None
                }
            }
        }
        None => None,
    };
    // A texture without `Kd` stands alone (reflectance 1 times the texel).
    // Neither says nothing of the colour, like an OBJ without materials, so
    // it gets the same grey (a black surface would be a guess, and a wrong
    // one for every file that simply leaves `Kd` out).
    let kd = match (mtl.diffuse, &texture) {
        (Some(kd), _) => kd,
        (None, Some(_)) => [1.0; 3],
        (None, None) => {
            warnings.push(format!(
                "{what} has neither `Kd` nor a `map_Kd` that can be read: using a diffuse grey of reflectance {DEFAULT_REFLECTANCE}"
            ));
            [DEFAULT_REFLECTANCE; 3]
        }
    };
    finite(&what, "Kd", &kd)?;
    let largest = texture.as_ref().map_or(Vec3::ONE, |t| t.largest_texel());
    let product = Vec3::from(kd) * largest;
    let kd = if product.max_element() >= 1.0 {
        warnings.push(format!(
            "{what}: `Kd` {kd:?}{} has a channel >= 1; lowered to {MTL_REFLECTANCE_LIMIT} so that the surface does not reflect all the light it receives",
            if texture.is_some() { " times the texture's largest texel" } else { "" },
        ));
        let limit =
            Vec3::splat(MTL_REFLECTANCE_LIMIT) / largest.max(Vec3::splat(f32::MIN_POSITIVE));
        Vec3::from(kd).min(limit).to_array()
    } else {
        kd
    };
    // tobj reads `Ke` itself (it is no unknown parameter).
    let ke = mtl.emissive.filter(|e| e.iter().any(|&c| c > 0.0));
    materials.push(Material {
        name: mtl_name.to_string(),
        bsdf: Bsdf::Diffuse {
            reflectance: reflectance(&what, "Kd", kd)?,
            texture,
        },
        emission: emission(&what, ke, false)?,
    });
    Ok(materials.len() - 1)
}
