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

mod materials;
mod obj;

use materials::{build_material, resolve_material};
use obj::ObjFile;

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

#[cfg(test)]
mod tests;
