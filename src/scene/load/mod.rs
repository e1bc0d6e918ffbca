//! Reading `scene.toml` and its OBJ meshes into a validated [`Scene`].
//!
//! Parsing happens in two steps: serde reads the TOML into the `*Toml` structs
//! below (unknown keys are errors, and every table keeps its span so that
//! later errors can name the line), then `build_*` checks values and turns
//! them into the scene's plain data. Every error names the file and the line
//! or field at fault.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{anyhow, bail, ensure, Context, Result};
use glam::{Quat, Vec2, Vec3};
use serde::Deserialize;
use toml::Spanned;

use super::wavefront::{check_obj, prepare_mtl};
use super::{
    Animation, Bsdf, CameraDesc, Emission, GlossyModel, Keyframe, Light, Material, Mesh, Motion,
    Object, PathKey, Scene, ViewSpace, WalkPath,
};
use crate::image::Texture;

type V3 = [f32; 3];

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneToml {
    animation: Option<AnimationToml>,
    #[serde(default)]
    materials: Vec<Spanned<MaterialToml>>,
    #[serde(default)]
    objects: Vec<Spanned<ObjectToml>>,
    #[serde(default)]
    lights: Vec<Spanned<LightToml>>,
    #[serde(default)]
    cameras: Vec<Spanned<CameraToml>>,
    view_space: Option<Spanned<ViewSpaceToml>>,
    #[serde(default)]
    paths: Vec<Spanned<PathToml>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct AnimationToml {
    start: f32,
    end: f32,
    fps: f32,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, tag = "type", rename_all = "lowercase")]
enum MaterialToml {
    Diffuse {
        name: String,
        reflectance: V3,
        texture: Option<PathBuf>,
        emission: Option<V3>,
        #[serde(default)]
        two_sided_emission: bool,
    },
    Glossy {
        name: String,
        diffuse: V3,
        specular: V3,
        roughness: f32,
        #[serde(default = "default_glossy_model")]
        model: String,
        emission: Option<V3>,
        #[serde(default)]
        two_sided_emission: bool,
    },
    Mirror {
        name: String,
        reflectance: V3,
    },
}

fn default_glossy_model() -> String {
    "ggx".into()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectToml {
    name: String,
    mesh: PathBuf,
    /// Which named object/group of the OBJ file; all of them when absent.
    group: Option<String>,
    /// A `[[materials]]` name; when absent, the OBJ's own (MTL) material.
    material: Option<String>,
    /// Object-space point that rotation and scale act about.
    pivot: Option<V3>,
    #[serde(default)]
    keyframes: Vec<Spanned<KeyframeToml>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyframeToml {
    time: f32,
    #[serde(default)]
    translate: V3,
    rotate: Option<RotationToml>,
    scale: Option<f32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RotationToml {
    axis: V3,
    degrees: f32,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, tag = "type", rename_all = "lowercase")]
enum LightToml {
    Point {
        position: V3,
        intensity: V3,
    },
    Sun {
        direction: V3,
        radiance: V3,
        angular_diameter: f32,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraToml {
    name: String,
    position: V3,
    look_at: Option<V3>,
    direction: Option<V3>,
    #[serde(default = "default_up")]
    up: V3,
    vfov: f32,
}

fn default_up() -> V3 {
    [0.0, 1.0, 0.0]
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, tag = "type", rename_all = "lowercase")]
enum ViewSpaceToml {
    Segment { a: V3, b: V3 },
    Rectangle { min: V3, max: V3 },
    Box { min: V3, max: V3 },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PathToml {
    name: String,
    keys: Vec<Spanned<CameraKeyToml>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraKeyToml {
    time: f32,
    position: V3,
    look_at: Option<V3>,
    direction: Option<V3>,
    #[serde(default = "default_up")]
    up: V3,
    vfov: f32,
}

/// Turns byte offsets into `file:line` locations for messages.
struct Source<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Source<'_> {
    fn at<T>(&self, item: &Spanned<T>) -> String {
        let line = self.text[..item.span().start].matches('\n').count() + 1;
        format!("{}:{line}", self.path.display())
    }
}

pub fn load(path: PathBuf) -> Result<Scene> {
    if let Some(why) = not_a_file(&path) {
        return Err(unreadable(format!("scene file {} {why}", path.display())));
    }
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read scene file {}", path.display()))?;
    let parsed: SceneToml = toml::from_str(&text)
        .map_err(|e| anyhow!("{}: {}", path.display(), e.to_string().trim_end()))?;
    let src = Source {
        path: &path,
        text: &text,
    };
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();

    let animation = match parsed.animation {
        Some(a) => {
            let what = format!("{}: [animation]", path.display());
            finite(&what, "start", &[a.start])?;
            finite(&what, "end", &[a.end])?;
            ensure!(
                a.end >= a.start,
                "{what}: end {} is before start {}",
                a.end,
                a.start
            );
            ensure!(
                a.fps.is_finite() && a.fps > 0.0,
                "{what}: fps {} must be positive",
                a.fps
            );
            Animation {
                start: a.start,
                end: a.end,
                fps: a.fps,
            }
        }
        None => Animation {
            start: 0.0,
            end: 0.0,
            fps: 30.0,
        },
    };

    let mut materials = Vec::new();
    for m in &parsed.materials {
        let material = build_material(&src.at(m), m.get_ref(), &dir)?;
        unique(
            &src.at(m),
            "material",
            &material.name,
            materials.iter().map(|x: &Material| &x.name),
        )?;
        materials.push(material);
    }

    let mut objects = Vec::new();
    let mut dropped_triangles = 0;
    let mut warnings = Vec::new();
    // Objects often share one OBJ file (one group each): read it once.
    let mut obj_files: HashMap<PathBuf, ObjFile> = HashMap::new();
    for o in &parsed.objects {
        let at = src.at(o);
        let o = o.get_ref();
        unique(
            &at,
            "object",
            &o.name,
            objects.iter().map(|x: &Object| &x.name),
        )?;
        let mesh_path = dir.join(&o.mesh);
        if !obj_files.contains_key(&mesh_path) {
            if let Some(why) = not_a_file(&mesh_path) {
                return Err(unreadable(format!(
                    "{at}: object `{}`: `mesh` {} {why}",
                    o.name,
                    mesh_path.display()
                )));
            }
            obj_files.insert(mesh_path.clone(), ObjFile::read(&mesh_path, &mut warnings)?);
        }
        let obj = &obj_files[&mesh_path];
        let (mesh, mtl_name, dropped) = obj
            .mesh(o.group.as_deref())
            .with_context(|| format!("{at}: object `{}`", o.name))?;
        // An object without a triangle is never seen, lit or hit: it can
        // only be a mistake (a wrong group, a model exported at a scale
        // that rounds it flat, a file of points or lines), and a warning
        // would let a scene render with something silently missing.
        if mesh.triangles.is_empty() {
            let part = match &o.group {
                Some(g) => format!("group `{g}` of {}", mesh_path.display()),
                None => mesh_path.display().to_string(),
            };
            if dropped > 0 {
                bail!(
                    "{at}: object `{}` has no triangles: the {dropped} triangle(s) of {part} all have zero area; fix the mesh or remove the object",
                    o.name
                );
            }
            bail!(
                "{at}: object `{}` has no triangles: {part} has no faces (points and lines are not drawn); fix `mesh` or `group`, or remove the object",
                o.name
            );
        }
        dropped_triangles += dropped;
        let material = resolve_material(
            &at,
            o,
            mtl_name.as_deref(),
            obj,
            &mut materials,
            &mut warnings,
        )?;
        let motion = build_motion(&src, &at, o, &mesh)?;
        objects.push(Object {
            name: o.name.clone(),
            mesh,
            material,
            motion,
        });
    }
    ensure!(
        !objects.is_empty(),
        "{}: the scene is empty: add an [[objects]] table with a mesh",
        path.display()
    );

    let mut lights = Vec::new();
    for l in &parsed.lights {
        lights.push(build_light(&src.at(l), l.get_ref())?);
    }

    let mut cameras = Vec::new();
    for c in &parsed.cameras {
        let at = src.at(c);
        let c = c.get_ref();
        unique(
            &at,
            "camera",
            &c.name,
            cameras.iter().map(|x: &CameraDesc| &x.name),
        )?;
        let what = format!("{at}: camera `{}`", c.name);
        let (direction, up) = pose(&what, c.position, c.look_at, c.direction, c.up, c.vfov)?;
        cameras.push(CameraDesc {
            name: c.name.clone(),
            position: c.position.into(),
            direction,
            up,
            vfov_deg: c.vfov,
        });
    }

    let view_space = parsed
        .view_space
        .as_ref()
        .map(|v| build_view_space(&src.at(v), v.get_ref()))
        .transpose()?;

    // A walk through an animated scene is a walk through its animation; a
    // static scene's paths may keep any times.
    let moving = objects.iter().any(|o| !o.motion.is_static());
    let mut paths = Vec::new();
    for p in &parsed.paths {
        let at = src.at(p);
        let p = p.get_ref();
        ensure!(!p.keys.is_empty(), "{at}: path `{}` has no keys", p.name);
        let mut keys: Vec<PathKey> = Vec::new();
        for k in &p.keys {
            let what = format!("{}: path `{}` key", src.at(k), p.name);
            let k = k.get_ref();
            finite(&what, "time", &[k.time])?;
            ensure!(
                !moving || (animation.start..=animation.end).contains(&k.time),
                "{what}: time {} lies outside the animation [{}, {}] s, where nothing would move: give times within it or extend [animation]",
                k.time,
                animation.start,
                animation.end
            );
            if let Some(prev) = keys.last() {
                ensure!(
                    k.time > prev.time,
                    "{what}: time {} is not after the previous key's time {} (keys must be in increasing time)",
                    k.time,
                    prev.time
                );
            }
            let (direction, up) = pose(&what, k.position, k.look_at, k.direction, k.up, k.vfov)?;
            keys.push(PathKey {
                time: k.time,
                position: k.position.into(),
                direction,
                up,
                vfov_deg: k.vfov,
            });
        }
        paths.push(WalkPath {
            name: p.name.clone(),
            keys,
        });
    }

    Ok(Scene {
        source: path,
        objects,
        materials,
        lights,
        animation,
        cameras,
        view_space,
        paths,
        dropped_triangles,
        warnings,
    })
}

fn unique<'a>(
    at: &str,
    kind: &str,
    name: &str,
    mut earlier: impl Iterator<Item = &'a String>,
) -> Result<()> {
    ensure!(
        !earlier.any(|n| n == name),
        "{at}: {kind} `{name}` is defined twice"
    );
    Ok(())
}

/// What keeps `path` from being read as a file, found without opening it:
/// opening a FIFO blocks until something writes to it, which may be never,
/// and "does not exist" would send the user looking for a file that is
/// there but is a folder or a link to itself.
fn not_a_file(path: &Path) -> Option<String> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() => None,
        Ok(m) if m.is_dir() => Some("is a folder, not a file".into()),
        Ok(m) => Some(format!(
            "is {}, not a regular file",
            special_kind(&m.file_type())
        )),
        Err(e) if e.raw_os_error() == Some(ELOOP) => Some(
            "is a symlink loop (following its links leads back to itself); point it at a file"
                .into(),
        ),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => match std::fs::read_link(path) {
            Ok(target) => Some(format!(
                "is a symlink to {}, which does not exist",
                target.display()
            )),
            Err(_) => Some("does not exist".into()),
        },
        Err(e) => Some(format!("cannot be read: {e}")),
    }
}

/// A file that cannot be read, as the I/O error it is, so that front ends
/// tell it from a scene that is wrong (the C API's `RW_IO`).
fn unreadable(message: String) -> anyhow::Error {
    std::io::Error::other(message).into()
}

/// The OS error of following too many symbolic links.
const ELOOP: i32 = if cfg!(target_os = "linux") { 40 } else { 62 };

#[cfg(unix)]
fn special_kind(t: &std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if t.is_fifo() {
        "a FIFO (named pipe)"
    } else if t.is_socket() {
        "a socket"
    } else if t.is_block_device() || t.is_char_device() {
        "a device"
    } else {
        "something else"
    }
}

#[cfg(not(unix))]
fn special_kind(_: &std::fs::FileType) -> &'static str {
    "something else"
}

/// A point or vector of the scene: finite, and no farther than
/// [`super::MAX_COORDINATE`] from the origin on any axis, so that what is
/// computed from it (differences, squared distances, products of those)
/// stays finite too. `1e38` is a finite `f32`, but a scene placed there
/// renders nothing and fails later with NaN cameras that name no field.
fn coordinates(what: &str, field: &str, values: &[f32]) -> Result<()> {
    finite(what, field, values)?;
    ensure!(
        values.iter().all(|v| v.abs() <= super::MAX_COORDINATE),
        "{what}: `{field}` {values:?} lies beyond ±{:e}, the farthest a coordinate may reach (so that distances between points stay finite): scale the scene down",
        super::MAX_COORDINATE
    );
    Ok(())
}

fn finite(what: &str, field: &str, values: &[f32]) -> Result<()> {
    ensure!(
        values.iter().all(|v| v.is_finite()),
        "{what}: `{field}` {values:?} is not finite (NaN or infinite)"
    );
    Ok(())
}

fn reflectance(what: &str, field: &str, v: V3) -> Result<Vec3> {
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

fn emission(what: &str, e: Option<V3>, two_sided: bool) -> Result<Option<Emission>> {
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

fn build_material(at: &str, m: &MaterialToml, dir: &Path) -> Result<Material> {
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
fn read_texture(what: &str, field: &str, path: &Path) -> Result<Arc<Texture>> {
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
const MTL_REFLECTANCE_LIMIT: f32 = 0.99;

/// The object material for an OBJ that names none (files from tools that
/// write no MTL): a mid grey.
const DEFAULT_MATERIAL: &str = "(default diffuse)";
const DEFAULT_REFLECTANCE: f32 = 0.5;

/// Picks the object's material: the named `[[materials]]` entry, else one
/// made from the OBJ's MTL material (Kd, map_Kd, Ke) on first use.
fn resolve_material(
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

/// The object's keyframes, each checked to keep `mesh` within
/// [`super::MAX_COORDINATE`]: `scale` can carry a small object out of
/// range where `translate` and `pivot` are in range. Between keys the
/// object's points then stay within a few times that bound (translation
/// and scale are interpolated linearly, rotation keeps lengths).
fn build_motion(src: &Source, at: &str, o: &ObjectToml, mesh: &Mesh) -> Result<Motion> {
    let what = format!("{at}: object `{}`", o.name);
    let pivot = o.pivot.unwrap_or([0.0; 3]);
    coordinates(&what, "pivot", &pivot)?;
    let mut keys: Vec<Keyframe> = Vec::new();
    for k in &o.keyframes {
        let kat = format!("{}: object `{}` keyframe", src.at(k), o.name);
        let k = k.get_ref();
        finite(&kat, "time", &[k.time])?;
        coordinates(&kat, "translate", &k.translate)?;
        if let Some(prev) = keys.last() {
            ensure!(
                k.time > prev.time,
                "{kat}: time {} is not after the previous keyframe's time {} (keyframes must be in increasing time)",
                k.time,
                prev.time
            );
        }
        let rotation = match &k.rotate {
            Some(r) => {
                coordinates(&kat, "rotate.axis", &r.axis)?;
                finite(&kat, "rotate.degrees", &[r.degrees])?;
                let axis = Vec3::from(r.axis).normalize_or_zero();
                ensure!(
                    axis != Vec3::ZERO,
                    "{kat}: `rotate.axis` {:?} has no length",
                    r.axis
                );
                Quat::from_axis_angle(axis, r.degrees.to_radians())
            }
            None => Quat::IDENTITY,
        };
        let scale = k.scale.unwrap_or(1.0);
        ensure!(
            scale.is_finite() && scale > 0.0,
            "{kat}: `scale` {scale} must be a positive number"
        );
        let key = Keyframe {
            time: k.time,
            translation: k.translate.into(),
            rotation,
            scale,
        };
        let pose = Motion::with_pivot(vec![key], pivot.into()).pose(k.time);
        if let Some(far) = farthest_corner(mesh, pose) {
            bail!(
                "{kat}: at time {} the object reaches {far}, beyond ±{:e}, the farthest a coordinate may reach (so that distances between points stay finite): lower `scale` or `translate`",
                k.time,
                super::MAX_COORDINATE
            );
        }
        keys.push(key);
    }
    Ok(Motion::with_pivot(keys, pivot.into()))
}

/// The world position of a corner of `mesh`'s bounds under `pose` that is
/// not finite or lies beyond [`super::MAX_COORDINATE`], if any.
fn farthest_corner(mesh: &Mesh, pose: glam::Affine3A) -> Option<Vec3> {
    let lo = mesh.positions.iter().fold(Vec3::INFINITY, |a, &p| a.min(p));
    let hi = mesh
        .positions
        .iter()
        .fold(Vec3::NEG_INFINITY, |a, &p| a.max(p));
    (0..8)
        .map(|i| {
            let pick = |bit: u32, l: f32, h: f32| if i & bit == 0 { l } else { h };
            pose.transform_point3(Vec3::new(
                pick(1, lo.x, hi.x),
                pick(2, lo.y, hi.y),
                pick(4, lo.z, hi.z),
            ))
        })
        .find(|w| !w.is_finite() || w.abs().max_element() > super::MAX_COORDINATE)
}

fn build_light(at: &str, l: &LightToml) -> Result<Light> {
    Ok(match l {
        LightToml::Point {
            position,
            intensity,
        } => {
            let what = format!("{at}: point light");
            coordinates(&what, "position", position)?;
            finite(&what, "intensity", intensity)?;
            ensure!(
                intensity.iter().all(|&c| c >= 0.0),
                "{what}: `intensity` {intensity:?} has a negative channel"
            );
            Light::Point {
                position: (*position).into(),
                intensity: (*intensity).into(),
            }
        }
        LightToml::Sun {
            direction,
            radiance,
            angular_diameter,
        } => {
            let what = format!("{at}: sun");
            coordinates(&what, "direction", direction)?;
            finite(&what, "radiance", radiance)?;
            let d = Vec3::from(*direction).normalize_or_zero();
            ensure!(
                d != Vec3::ZERO,
                "{what}: `direction` {direction:?} has no length"
            );
            ensure!(
                radiance.iter().all(|&c| c >= 0.0),
                "{what}: `radiance` {radiance:?} has a negative channel"
            );
            ensure!(
                angular_diameter.is_finite() && *angular_diameter > 0.0 && *angular_diameter < 90.0,
                "{what}: `angular_diameter` {angular_diameter} must lie in (0, 90) degrees"
            );
            Light::Sun {
                direction: d,
                radiance: (*radiance).into(),
                angular_diameter_deg: *angular_diameter,
            }
        }
    })
}

/// Validates a camera pose and returns its unit direction and up vector.
fn pose(
    what: &str,
    position: V3,
    look_at: Option<V3>,
    direction: Option<V3>,
    up: V3,
    vfov: f32,
) -> Result<(Vec3, Vec3)> {
    coordinates(what, "position", &position)?;
    coordinates(what, "up", &up)?;
    let dir = match (look_at, direction) {
        (Some(t), None) => {
            coordinates(what, "look_at", &t)?;
            Vec3::from(t) - Vec3::from(position)
        }
        (None, Some(d)) => {
            coordinates(what, "direction", &d)?;
            Vec3::from(d)
        }
        _ => bail!("{what}: give exactly one of `look_at` and `direction`"),
    };
    let dir = dir.normalize_or_zero();
    ensure!(
        dir != Vec3::ZERO,
        "{what}: the view direction has no length (`look_at` equals `position`?)"
    );
    let up = Vec3::from(up);
    ensure!(
        dir.cross(up).length() > 1e-6 * up.length().max(f32::MIN_POSITIVE),
        "{what}: `up` {up} is parallel to the view direction {dir}"
    );
    ensure!(
        vfov.is_finite() && vfov > 0.0 && vfov < 180.0,
        "{what}: `vfov` {vfov} must lie in (0, 180) degrees"
    );
    Ok((dir, up))
}

fn build_view_space(at: &str, v: &ViewSpaceToml) -> Result<ViewSpace> {
    let what = format!("{at}: [view_space]");
    Ok(match v {
        ViewSpaceToml::Segment { a, b } => {
            coordinates(&what, "a", a)?;
            coordinates(&what, "b", b)?;
            ensure!(a != b, "{what}: segment end points are equal");
            ViewSpace::Segment {
                a: (*a).into(),
                b: (*b).into(),
            }
        }
        ViewSpaceToml::Rectangle { min, max } | ViewSpaceToml::Box { min, max } => {
            coordinates(&what, "min", min)?;
            coordinates(&what, "max", max)?;
            let (lo, hi) = (Vec3::from(*min), Vec3::from(*max));
            ensure!(
                lo.cmple(hi).all(),
                "{what}: `min` {lo} is not below `max` {hi} on every axis"
            );
            let flat = (hi - lo).to_array().iter().filter(|&&e| e == 0.0).count();
            if matches!(v, ViewSpaceToml::Rectangle { .. }) {
                ensure!(
                    flat == 1,
                    "{what}: a rectangle must have exactly one zero extent, `max - min` = {}",
                    hi - lo
                );
                ViewSpace::Rectangle { min: lo, max: hi }
            } else {
                ensure!(
                    flat == 0,
                    "{what}: a box must have extent on every axis, `max - min` = {}",
                    hi - lo
                );
                ViewSpace::Box { min: lo, max: hi }
            }
        }
    })
}

/// One OBJ file with its models and MTL materials.
struct ObjFile {
    path: PathBuf,
    models: Vec<tobj::Model>,
    materials: Vec<tobj::Material>,
    /// The MTL file each material came from, for messages about it.
    mtl_files: HashMap<String, PathBuf>,
}

impl ObjFile {
    /// A missing MTL file is a warning (the objects fall back to the
    /// default material); one that does not parse is an error naming it.
    /// The caller has checked that `path` is a regular file.
    fn read(path: &Path, warnings: &mut Vec<String>) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read mesh {}", path.display()))?;
        check_obj(path, &text)?;
        let opts = tobj::LoadOptions {
            single_index: true,
            triangulate: true,
            ignore_points: true,
            ignore_lines: true,
        };
        let dir = path.parent().unwrap_or(Path::new("."));
        let mtl_warnings = std::cell::RefCell::new(Vec::new());
        let mtl_error = std::cell::RefCell::new(None);
        let mtl_files = std::cell::RefCell::new(HashMap::new());
        let (models, materials) = tobj::load_obj_buf(&mut text.as_bytes(), &opts, |name| {
            let mtl = dir.join(name);
            let read = match not_a_file(&mtl) {
                Some(why) => Err(why),
                None => std::fs::read_to_string(&mtl).map_err(|e| format!("cannot be read: {e}")),
            };
            let text = match read {
                Ok(text) => text,
                Err(why) => {
                    mtl_warnings.borrow_mut().push(format!(
                        "{}: MTL file {} {why}: its materials fall back to the default",
                        path.display(),
                        mtl.display()
                    ));
                    return Ok(Default::default());
                }
            };
            let (text, w) = match prepare_mtl(&mtl, &text) {
                Ok(prepared) => prepared,
                Err(e) => {
                    *mtl_error.borrow_mut() = Some(e);
                    return Err(tobj::LoadError::MaterialParseError);
                }
            };
            mtl_warnings.borrow_mut().extend(w);
            tobj::load_mtl_buf(&mut text.as_bytes())
                .inspect(|(materials, _)| {
                    let mut files = mtl_files.borrow_mut();
                    for m in materials {
                        files.insert(m.name.clone(), mtl.clone());
                    }
                })
                .inspect_err(|e| {
                    *mtl_error.borrow_mut() =
                        Some(anyhow!("cannot read MTL file {}: {e}", mtl.display()));
                })
        })
        .map_err(|e| anyhow!("cannot read mesh {}: {e}", path.display()))?;
        if let Some(e) = mtl_error.into_inner() {
            return Err(e);
        }
        warnings.extend(mtl_warnings.into_inner());
        // An MTL failure was reported above; none are left here.
        let materials = materials.unwrap_or_default();
        Ok(Self {
            path: path.to_path_buf(),
            models,
            materials,
            mtl_files: mtl_files.into_inner(),
        })
    }

    /// The triangles of `group` (or all groups) with zero-area triangles
    /// dropped and counted, and the MTL material name the group uses.
    fn mesh(&self, group: Option<&str>) -> Result<(Mesh, Option<String>, usize)> {
        let models: Vec<&tobj::Model> = match group {
            Some(g) => self.models.iter().filter(|m| m.name == g).collect(),
            None => self.models.iter().collect(),
        };
        if models.is_empty() {
            let names: Vec<&str> = self.models.iter().map(|m| m.name.as_str()).collect();
            bail!(
                "{}: no group `{}` in the mesh (groups: {})",
                self.path.display(),
                group.unwrap_or("*"),
                names.join(", ")
            );
        }
        let mut mesh = Mesh::default();
        let with_uvs = models.iter().all(|m| !m.mesh.texcoords.is_empty());
        let mut uvs = Vec::new();
        let mut dropped = 0;
        let mut mtl = None;
        for m in models {
            let base = mesh.positions.len() as u32;
            let p = &m.mesh.positions;
            ensure!(
                p.iter().all(|c| c.is_finite()),
                "{}: group `{}` has a vertex coordinate that is not finite",
                self.path.display(),
                m.name
            );
            if let Some(c) = p.iter().find(|c| c.abs() > super::MAX_COORDINATE) {
                bail!(
                    "{}: group `{}` has a vertex coordinate {c:e} beyond ±{:e}, the farthest a coordinate may reach (so that distances between points stay finite): scale the mesh down",
                    self.path.display(),
                    m.name,
                    super::MAX_COORDINATE
                );
            }
            mesh.positions
                .extend(p.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])));
            if with_uvs {
                uvs.extend(
                    m.mesh
                        .texcoords
                        .chunks_exact(2)
                        .map(|c| Vec2::new(c[0], c[1])),
                );
            }
            for t in m.mesh.indices.chunks_exact(3) {
                let tri = [base + t[0], base + t[1], base + t[2]];
                if mesh.triangle_area(tri) > 0.0 {
                    mesh.triangles.push(tri);
                } else {
                    dropped += 1;
                }
            }
            if mtl.is_none() {
                mtl = m
                    .mesh
                    .material_id
                    .and_then(|i| self.materials.get(i))
                    .map(|x| x.name.clone());
            }
        }
        mesh.uvs = with_uvs.then_some(uvs);
        Ok((mesh, mtl, dropped))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const OBJ: &str = "o quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n\
                       o sliver\nv 0 0 0\nv 1 0 0\nv 2 0 0\nf 5 6 7\n";

    fn scene_dir(toml: &str) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("m.obj"), OBJ).unwrap();
        let path = dir.path().join("scene.toml");
        std::fs::write(&path, toml).unwrap();
        (dir, path)
    }

    const GOOD: &str = r#"
[animation]
start = 0
end = 1
fps = 30

[[materials]]
name = "white"
type = "diffuse"
reflectance = [0.5, 0.5, 0.5]

[[objects]]
name = "quad"
mesh = "m.obj"
group = "quad"
material = "white"
pivot = [0.5, 0.5, 0]
[[objects.keyframes]]
time = 0
[[objects.keyframes]]
time = 1
translate = [1, 0, 0]
rotate = { axis = [0, 0, 1], degrees = 90 }

[[cameras]]
name = "main"
position = [0.5, 0.5, -3]
look_at = [0.5, 0.5, 0]
vfov = 40
"#;

    fn load_err(toml: &str) -> String {
        let (_d, path) = scene_dir(toml);
        format!("{:#}", Scene::load(path).unwrap_err())
    }

    #[test]
    fn good_scene_loads() {
        let (_d, path) = scene_dir(GOOD);
        let s = Scene::load(path).unwrap();
        assert_eq!(s.objects.len(), 1);
        assert_eq!(s.objects[0].mesh.triangles.len(), 2);
        assert!(!s.is_static());
        // The pivot stays put while the quad turns; translation moves it.
        let c = s.at(1.0)[0].transform_point3(Vec3::new(0.5, 0.5, 0.0));
        assert!((c - Vec3::new(1.5, 0.5, 0.0)).length() < 1e-5, "{c}");
        assert_eq!(s.camera("main").unwrap().direction, Vec3::Z);
        assert!(s.camera("nope").unwrap_err().to_string().contains("main"));
    }

    #[test]
    fn zero_area_triangles_are_dropped_and_counted() {
        let toml = GOOD.replace("group = \"quad\"\n", "");
        let (_d, path) = scene_dir(&toml);
        let s = Scene::load(path).unwrap();
        assert_eq!(s.dropped_triangles, 1);
        assert_eq!(s.objects[0].mesh.triangles.len(), 2);
    }

    #[test]
    fn bad_inputs_name_what_is_wrong() {
        let cases: &[(&str, &str, &[&str])] = &[
            (
                "reflectance = [0.5, 0.5, 0.5]",
                "reflectance = [1.0, 0.5, 0.5]",
                &["white", ">= 1", "scene.toml:7"],
            ),
            (
                "reflectance = [0.5, 0.5, 0.5]",
                "reflectance = [nan, 0.5, 0.5]",
                &["reflectance", "not finite"],
            ),
            (
                "material = \"white\"",
                "material = \"gold\"",
                &["gold", "white", "quad"],
            ),
            (
                "translate = [1, 0, 0]",
                "translate = [inf, 0, 0]",
                &["translate", "not finite"],
            ),
            ("time = 1\n", "time = -1\n", &["increasing", "keyframe"]),
            (
                "mesh = \"m.obj\"",
                "mesh = \"missing.obj\"",
                &["missing.obj", "does not exist"],
            ),
            (
                "group = \"quad\"",
                "group = \"sliver\"",
                &["object `quad` has no triangles", "sliver", "zero area"],
            ),
            ("group = \"quad\"", "group = \"cube\"", &["cube", "quad"]),
            ("vfov = 40", "vfov = 400", &["vfov", "main"]),
            (
                "translate = [1, 0, 0]",
                "translate = [1e38, 0, 0]",
                &["object `quad` keyframe", "`translate`", "beyond"],
            ),
            (
                "translate = [1, 0, 0]",
                "translate = [1, 0, 0]\nscale = 1e38",
                &["object `quad` keyframe", "at time 1", "`scale`"],
            ),
            (
                "pivot = [0.5, 0.5, 0]",
                "pivot = [0.5, -1e38, 0]",
                &["object `quad`", "`pivot`", "beyond"],
            ),
            (
                "position = [0.5, 0.5, -3]",
                "position = [0.5, 0.5, -3e38]",
                &["camera `main`", "`position`", "beyond"],
            ),
            (
                "look_at = [0.5, 0.5, 0]",
                "look_at = [3e38, 0.5, 0]",
                &["camera `main`", "`look_at`", "beyond"],
            ),
            ("fps = 30", "fps = 30\nspeed = 2", &["speed"]),
            ("type = \"diffuse\"", "type = \"velvet\"", &["velvet"]),
            (
                "look_at = [0.5, 0.5, 0]",
                "look_at = [0.5, 0.5, -3]",
                &["direction"],
            ),
        ];
        for (from, to, needles) in cases {
            assert!(GOOD.contains(from), "{from}");
            let msg = load_err(&GOOD.replacen(from, to, 1));
            assert!(
                msg.contains("scene.toml") || msg.contains(".obj"),
                "no file named in: {msg}"
            );
            for n in *needles {
                assert!(msg.contains(n), "`{n}` missing from: {msg}");
            }
        }
    }

    /// A walk path through an animated scene stays within its animation
    /// (beyond it nothing would move); a static scene's paths keep any
    /// times.
    #[test]
    fn path_keys_of_an_animated_scene_lie_within_the_animation() {
        let path = "\n[[paths]]\nname = \"walk\"\n[[paths.keys]]\ntime = 0\nposition = [0, 0, -3]\ndirection = [0, 0, 1]\nvfov = 40\n[[paths.keys]]\ntime = 5\nposition = [1, 0, -3]\ndirection = [0, 0, 1]\nvfov = 40\n";
        let msg = load_err(&format!("{GOOD}{path}"));
        assert!(
            msg.contains("path `walk` key")
                && msg.contains("time 5 lies outside the animation [0, 1] s"),
            "{msg}"
        );
        let still = GOOD.replace(
            "translate = [1, 0, 0]\nrotate = { axis = [0, 0, 1], degrees = 90 }\n",
            "",
        );
        assert_ne!(still, GOOD);
        let (_d, p) = scene_dir(&format!("{still}{path}"));
        let s = Scene::load(p).unwrap_or_else(|e| panic!("{e:#}"));
        assert!(s.is_static());
        assert!(s.check_time(-1.0).is_ok() && s.check_time(f32::NAN).is_err());
    }

    #[test]
    fn names_must_be_unique() {
        let twice = format!("{GOOD}\n[[cameras]]\nname = \"main\"\nposition = [0, 0, -1]\ndirection = [0, 0, 1]\nvfov = 30\n");
        let msg = load_err(&twice);
        assert!(msg.contains("camera `main` is defined twice"), "{msg}");
    }

    #[test]
    fn malformed_files_are_errors() {
        assert!(load_err("[[objects]\n").contains("scene.toml"));
        assert!(load_err("").contains("empty"));
        let dir = tempfile::tempdir().unwrap();
        let err = format!(
            "{:#}",
            Scene::load(dir.path().join("none.toml")).unwrap_err()
        );
        assert!(err.contains("none.toml"), "{err}");
    }

    /// A white texel (an 8-bit 255) under a reflectance below 1 loads; a
    /// product of 1 is refused, naming the texture.
    #[test]
    fn texture_is_checked_as_a_product_with_the_reflectance() {
        let png = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/wavefront/checker.png");
        let textured = GOOD.replace(
            "reflectance = [0.5, 0.5, 0.5]",
            "reflectance = [0.8, 0.8, 0.8]\ntexture = \"t.png\"",
        );
        let (d, path) = scene_dir(&textured);
        std::fs::copy(png, d.path().join("t.png")).unwrap();
        let s = Scene::load(&path).unwrap_or_else(|e| panic!("{e:#}"));
        assert!(matches!(
            &s.materials[0].bsdf,
            Bsdf::Diffuse {
                texture: Some(_),
                ..
            }
        ));
        // A high-dynamic-range texel of 2 under 0.8 is a reflectance of 1.6.
        exr::prelude::write_rgb_file(d.path().join("t.exr"), 2, 1, |_, _| {
            (2.0f32, 0.1f32, 0.1f32)
        })
        .unwrap();
        std::fs::write(&path, textured.replace("t.png", "t.exr")).unwrap();
        let msg = format!("{:#}", Scene::load(&path).unwrap_err());
        assert!(
            msg.contains("t.exr") && msg.contains("largest texel"),
            "{msg}"
        );
    }

    #[test]
    fn nan_in_obj_is_an_error() {
        let (d, path) = scene_dir(GOOD);
        std::fs::write(
            d.path().join("m.obj"),
            "o quad\nv 0 0 0\nv nan 0 0\nv 1 1 0\nf 1 2 3\n",
        )
        .unwrap();
        let msg = format!("{:#}", Scene::load(path).unwrap_err());
        assert!(msg.contains("m.obj") && msg.contains("finite"), "{msg}");
    }
}
