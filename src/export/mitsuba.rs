//! Export of a scene at one time to Mitsuba 3 (`scene.xml`, version 3.0.0,
//! plus one OBJ per object in world space), set up so that Mitsuba's `path`
//! integrator converges to the same image as our path tracer:
//!
//! - camera: `perspective` with `fov_axis="y"` and the same pose; Mitsuba's
//!   `lookat` puts `up x forward` on the image's left, as ours does;
//! - film: `hdrfilm`, RGB, with a `box` filter (each sample lands in its own
//!   pixel with equal weight, as in our uniform pixel averaging);
//! - `path` integrator with the same `max_depth` (Mitsuba counts path
//!   segments exactly as we do; -1 for unlimited), `independent` sampler;
//! - Lambertian → `twosided` `diffuse` (textures baked with the reflectance
//!   into a linear PFM, bilinear and repeating like ours);
//! - glossy `d/π + s·GGX` → `twosided` `blendbsdf` of `diffuse(d/(1-w))` and
//!   `roughconductor(material="none", ggx, alpha, s/w)`, which is the same sum
//!   for any `w` in (0, 1): Mitsuba's rough conductor without Fresnel is
//!   `s·D·G1(wi)G1(wo)/(4 cos cos)` with visible-normal sampling, as ours.
//!   Mitsuba has no Ward lobe: Ward materials are exported as GGX with the
//!   same alpha, noted in the file;
//! - mirror → `twosided` `conductor(material="none")`;
//! - emission → `area` emitter, one-sided like ours; two-sided emission has no
//!   Mitsuba equivalent and is refused;
//! - point light → `point`;
//! - sun → a distant emitting disk subtending the sun's cone from the scene's
//!   centre, `1e4` scene radii away: exact up to a parallax of 1e-4 rad
//!   (a `directional` emitter would lose the disk's size and with it the
//!   sun's reflection in mirrors and glossy lobes).

use std::fmt::Write as _;
use std::fs;
use std::path::Path;

use anyhow::{bail, Context, Result};
use glam::Vec3;

use crate::camera::{Camera, Projection};
use crate::image::Texture;
use crate::output::{numbered, Contents, Folder};
use crate::scene::{Bsdf, GlossyModel, Light, Material, Scene};

/// How many scene radii away the sun's disk is placed.
const SUN_DISTANCE_RADII: f32 = 1e4;

/// What an export writes into its folder.
pub const CONTENTS: Contents = Contents {
    what: "a Mitsuba export",
    owns: |name, is_dir| {
        !is_dir
            && (name == "scene.xml"
                || numbered(name, "mesh_", &["obj"])
                || numbered(name, "texture_", &["pfm"]))
    },
};

/// Writes `<dir>/scene.xml` and its meshes (and textures) for `scene` at
/// `time`, seen by `camera`, rendered with `spp` samples per pixel. The
/// folder is replaced whole, so its scene and meshes are always of one
/// export.
pub fn export(
    scene: &Scene,
    time: f32,
    camera: &Camera,
    spp: u32,
    max_depth: Option<u32>,
    dir: &Path,
) -> Result<()> {
    let Projection::Perspective { vfov_deg } = camera.projection else {
        bail!(
            "Mitsuba export: the {} projection has no Mitsuba camera; use a perspective camera",
            camera.projection.name()
        );
    };
    let folder = Folder::begin(dir, CONTENTS)?;
    write_scene(scene, time, camera, vfov_deg, spp, max_depth, folder.path())?;
    folder.finish()?;
    Ok(())
}

fn write_scene(
    scene: &Scene,
    time: f32,
    camera: &Camera,
    vfov_deg: f32,
    spp: u32,
    max_depth: Option<u32>,
    dir: &Path,
) -> Result<()> {
    let mut xml = String::new();
    let w = &mut xml;
    writeln!(w, r#"<?xml version="1.0" encoding="utf-8"?>"#)?;
    writeln!(
        w,
        "<!-- {} at t = {time}, exported for validation. -->",
        comment(&scene.source.display().to_string())
    )?;
    writeln!(w, r#"<scene version="3.0.0">"#)?;
    // Defaults that `mitsuba -D spp=...` or `load_file(..., spp=...)` may
    // override.
    let depth = max_depth.map_or(-1, |d| d as i64);
    writeln!(w, r#"  <default name="spp" value="{spp}"/>"#)?;
    writeln!(w, r#"  <default name="max_depth" value="{depth}"/>"#)?;
    writeln!(
        w,
        r#"  <integrator type="path"><integer name="max_depth" value="$max_depth"/></integrator>"#
    )?;
    let target = camera.position + camera.forward;
    writeln!(w, r#"  <sensor type="perspective">"#)?;
    writeln!(w, r#"    <string name="fov_axis" value="y"/>"#)?;
    writeln!(w, r#"    <float name="fov" value="{vfov_deg}"/>"#)?;
    writeln!(
        w,
        r#"    <transform name="to_world"><lookat origin="{}" target="{}" up="{}"/></transform>"#,
        v3(camera.position),
        v3(target),
        v3(camera.up)
    )?;
    writeln!(
        w,
        r#"    <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>"#
    )?;
    writeln!(w, r#"    <film type="hdrfilm">"#)?;
    writeln!(
        w,
        r#"      <integer name="width" value="{}"/><integer name="height" value="{}"/>"#,
        camera.width, camera.height
    )?;
    writeln!(w, r#"      <string name="pixel_format" value="rgb"/>"#)?;
    writeln!(w, r#"      <rfilter type="box"/>"#)?;
    writeln!(w, "    </film>\n  </sensor>")?;

    for ((k, obj), xf) in scene.objects.iter().enumerate().zip(scene.at(time)) {
        let material = &scene.materials[obj.material];
        let file = format!("mesh_{k}.obj");
        write_obj(
            &dir.join(&file),
            &obj.mesh.positions,
            &obj.mesh.triangles,
            obj.mesh.uvs.as_deref(),
            |p| xf.transform_point3(p),
        )?;
        writeln!(w, "  <!-- object {k}: {} -->", comment(&obj.name))?;
        writeln!(w, r#"  <shape type="obj">"#)?;
        writeln!(w, r#"    <string name="filename" value="{file}"/>"#)?;
        writeln!(w, r#"    <boolean name="face_normals" value="true"/>"#)?;
        write_bsdf(w, material, obj.material, dir)?;
        if let Some(em) = material.emission {
            if em.two_sided {
                bail!(
                    "Mitsuba export: material `{}` emits from both sides, which Mitsuba's area emitter cannot",
                    material.name
                );
            }
            writeln!(
                w,
                r#"    <emitter type="area"><rgb name="radiance" value="{}"/></emitter>"#,
                v3(em.radiance)
            )?;
        }
        writeln!(w, "  </shape>")?;
    }

    let (lo, hi) = scene.bounds(time);
    for light in &scene.lights {
        match *light {
            Light::Point {
                position,
                intensity,
            } => writeln!(
                w,
                r#"  <emitter type="point"><point name="position" value="{}"/><rgb name="intensity" value="{}"/></emitter>"#,
                v3(position),
                v3(intensity)
            )?,
            Light::Sun {
                direction,
                radiance,
                angular_diameter_deg,
            } => write_sun(w, direction, radiance, angular_diameter_deg, lo, hi)?,
        }
    }
    writeln!(w, "</scene>")?;
    let path = dir.join("scene.xml");
    fs::write(&path, xml).with_context(|| format!("writing {}", path.display()))
}

fn write_bsdf(w: &mut String, material: &Material, index: usize, dir: &Path) -> Result<()> {
    writeln!(w, "    <!-- material {} -->", comment(&material.name))?;
    writeln!(w, r#"    <bsdf type="twosided">"#)?;
    match &material.bsdf {
        Bsdf::Diffuse {
            reflectance,
            texture,
        } => match texture {
            None => writeln!(
                w,
                r#"      <bsdf type="diffuse"><rgb name="reflectance" value="{}"/></bsdf>"#,
                v3(*reflectance)
            )?,
            Some(tex) => {
                let file = format!("texture_{index}.pfm");
                write_pfm(&dir.join(&file), tex, *reflectance)?;
                writeln!(
                    w,
                    r#"      <bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="{file}"/><boolean name="raw" value="true"/><string name="filter_type" value="bilinear"/><string name="wrap_mode" value="repeat"/></texture></bsdf>"#
                )?
            }
        },
        Bsdf::Glossy {
            diffuse,
            specular,
            roughness,
            model,
        } => {
            if *model == GlossyModel::Ward {
                writeln!(
                    w,
                    "      <!-- Ward lobe: Mitsuba has none; exported as GGX with the same alpha. -->"
                )?;
            }
            let conductor = |w: &mut String, s: Vec3| {
                writeln!(
                    w,
                    r#"      <bsdf type="roughconductor"><string name="material" value="none"/><string name="distribution" value="ggx"/><float name="alpha" value="{roughness}"/><rgb name="specular_reflectance" value="{}"/></bsdf>"#,
                    v3(s)
                )
            };
            let (dm, sm) = (diffuse.max_element(), specular.max_element());
            if sm <= 0.0 {
                writeln!(
                    w,
                    r#"      <bsdf type="diffuse"><rgb name="reflectance" value="{}"/></bsdf>"#,
                    v3(*diffuse)
                )?;
            } else if dm <= 0.0 {
                conductor(w, *specular)?;
            } else {
                // f = (1 - wt) f_diffuse + wt f_conductor, so the nested
                // reflectances are divided by their weights.
                let wt = sm / (dm + sm);
                writeln!(
                    w,
                    r#"      <bsdf type="blendbsdf"><float name="weight" value="{wt}"/>"#
                )?;
                writeln!(
                    w,
                    r#"      <bsdf type="diffuse"><rgb name="reflectance" value="{}"/></bsdf>"#,
                    v3(*diffuse / (1.0 - wt))
                )?;
                conductor(w, *specular / wt)?;
                writeln!(w, "      </bsdf>")?;
            }
        }
        Bsdf::Mirror { reflectance } => writeln!(
            w,
            r#"      <bsdf type="conductor"><string name="material" value="none"/><rgb name="specular_reflectance" value="{}"/></bsdf>"#,
            v3(*reflectance)
        )?,
    }
    writeln!(w, "    </bsdf>")?;
    Ok(())
}

/// The sun as an emitting disk far away, facing the scene, of the radius that
/// subtends the sun's angular diameter from the centre of the scene.
fn write_sun(
    w: &mut String,
    direction: Vec3,
    radiance: Vec3,
    angular_diameter_deg: f32,
    lo: Vec3,
    hi: Vec3,
) -> Result<()> {
    let dir = direction.normalize();
    let centre = 0.5 * (lo + hi);
    let distance = SUN_DISTANCE_RADII * (0.5 * (hi - lo).length()).max(f32::MIN_POSITIVE);
    let radius = distance * (0.5 * angular_diameter_deg).to_radians().tan();
    let origin = centre + dir * distance;
    let up = dir.any_orthonormal_vector();
    writeln!(
        w,
        "  <!-- sun: {angular_diameter_deg}° disk, radiance {}, {SUN_DISTANCE_RADII} scene radii away -->",
        v3(radiance)
    )?;
    writeln!(w, r#"  <shape type="disk">"#)?;
    writeln!(
        w,
        r#"    <transform name="to_world"><scale value="{radius}"/><lookat origin="{}" target="{}" up="{}"/></transform>"#,
        v3(origin),
        v3(centre),
        v3(up)
    )?;
    writeln!(
        w,
        r#"    <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>"#
    )?;
    writeln!(
        w,
        r#"    <emitter type="area"><rgb name="radiance" value="{}"/></emitter>"#,
        v3(radiance)
    )?;
    writeln!(w, "  </shape>")?;
    Ok(())
}

fn write_obj(
    path: &Path,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    uvs: Option<&[glam::Vec2]>,
    to_world: impl Fn(Vec3) -> Vec3,
) -> Result<()> {
    let mut s = String::new();
    for &p in positions {
        let p = to_world(p);
        writeln!(s, "v {} {} {}", p.x, p.y, p.z)?;
    }
    if let Some(uvs) = uvs {
        for uv in uvs {
            writeln!(s, "vt {} {}", uv.x, uv.y)?;
        }
    }
    for t in triangles {
        let [a, b, c] = t.map(|i| i + 1);
        if uvs.is_some() {
            writeln!(s, "f {a}/{a} {b}/{b} {c}/{c}")?;
        } else {
            writeln!(s, "f {a} {b} {c}")?;
        }
    }
    fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

/// A linear RGB PFM of `texture` times `scale` (PFM rows run bottom to top).
fn write_pfm(path: &Path, texture: &Texture, scale: Vec3) -> Result<()> {
    let (wd, ht) = (texture.width as usize, texture.height as usize);
    let mut bytes = format!("PF\n{wd} {ht}\n-1.0\n").into_bytes();
    for row in (0..ht).rev() {
        for t in &texture.texels[row * wd..(row + 1) * wd] {
            for c in (*t * scale).to_array() {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
}

fn v3(v: Vec3) -> String {
    format!("{}, {}, {}", v.x, v.y, v.z)
}

/// Text safe inside an XML comment.
fn comment(s: &str) -> String {
    s.replace("--", "- -")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(name: &str) -> Scene {
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes");
        Scene::load(dir.join(name).join("scene.toml")).unwrap()
    }

    #[test]
    fn cornell_box_exports_posed_meshes_and_one_sided_light() {
        let scene = load("cornell-box");
        let camera = scene.camera("main").unwrap().perspective(32, 24).unwrap();
        let dir = tempfile::tempdir().unwrap();
        export(&scene, 1.0, &camera, 16, None, dir.path()).unwrap();
        let xml = fs::read_to_string(dir.path().join("scene.xml")).unwrap();
        for needle in [
            r#"<scene version="3.0.0">"#,
            r#"<default name="spp" value="16"/>"#,
            r#"<default name="max_depth" value="-1"/>"#,
            r#"<rfilter type="box"/>"#,
            r#"<float name="fov" value="39.3077"#,
            r#"<emitter type="area"><rgb name="radiance" value="17, 12, 4"/>"#,
            r#"<integer name="width" value="32"/><integer name="height" value="24"/>"#,
        ] {
            assert!(xml.contains(needle), "missing {needle} in\n{xml}");
        }
        assert_eq!(
            xml.matches("<shape type=\"obj\">").count(),
            scene.objects.len()
        );
        // The short box (object 6) is written where it stands at t = 1.
        let obj = fs::read_to_string(dir.path().join("mesh_6.obj")).unwrap();
        let first: Vec<f32> = obj.lines().next().unwrap()[2..]
            .split(' ')
            .map(|v| v.parse().unwrap())
            .collect();
        let p = scene.objects[6]
            .motion
            .pose(1.0)
            .transform_point3(scene.objects[6].mesh.positions[0]);
        assert_eq!(first, p.to_array().to_vec());
    }

    #[test]
    fn two_sided_emission_and_fisheye_are_refused() {
        let scene = load("furnace");
        let camera = scene.camera("main").unwrap().perspective(8, 8).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let err = export(&scene, 0.0, &camera, 4, Some(3), dir.path()).unwrap_err();
        assert!(format!("{err:#}").contains("both sides"), "{err:#}");
        let fish = scene
            .camera("main")
            .unwrap()
            .with_projection(Projection::Fisheye, 8, 8)
            .unwrap();
        assert!(export(&scene, 0.0, &fish, 4, None, dir.path()).is_err());
    }

    #[test]
    fn pfm_rows_run_bottom_up() {
        let dir = tempfile::tempdir().unwrap();
        let tex = Texture {
            source: "t.png".into(),
            width: 1,
            height: 2,
            texels: vec![Vec3::splat(0.25), Vec3::splat(0.5)],
        };
        let path = dir.path().join("t.pfm");
        write_pfm(&path, &tex, Vec3::new(1.0, 2.0, 1.0)).unwrap();
        let bytes = fs::read(&path).unwrap();
        let header = b"PF\n1 2\n-1.0\n";
        assert_eq!(&bytes[..header.len()], header);
        let floats: Vec<f32> = bytes[header.len()..]
            .chunks(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect();
        // Bottom row (0.5) first, then the top row (0.25), green doubled.
        assert_eq!(floats, vec![0.5, 1.0, 0.5, 0.25, 0.5, 0.25]);
    }
}
