//! The scene description: geometry, materials, lights, rigid motion, cameras,
//! view space and walk-through paths, parsed from `scene.toml` and validated.
//!
//! This is plain data. Runtime structures (ray engines, light samplers) are
//! built from it by the modules that need them; time is always a parameter
//! (`Scene::at(t)`), never state kept here.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{anyhow, ensure, Result};
use glam::{Affine3A, Vec2, Vec3};

use crate::camera::{Camera, Projection};
use crate::image::Texture;
use crate::ray::{offset_origin, Ray};

pub mod hash;
mod load;
mod motion;
mod wavefront;

pub use motion::{Keyframe, Motion};

/// The farthest from the origin, on any axis, that a scene's points,
/// cameras and lights may lie (in scene units). Far beyond any scene's
/// size (the bundled scenes reach 1e7), and far enough below `f32::MAX`
/// (3.4e38) that differences of points, their squared lengths and
/// products of those stay finite.
pub const MAX_COORDINATE: f32 = 1e15;

/// A validated scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The `scene.toml` this was read from (meshes are relative to its folder).
    pub source: PathBuf,
    pub objects: Vec<Object>,
    pub materials: Vec<Material>,
    /// Point lights and the sun; area lights are the objects whose material
    /// emits.
    pub lights: Vec<Light>,
    pub animation: Animation,
    pub cameras: Vec<CameraDesc>,
    pub view_space: Option<ViewSpace>,
    pub paths: Vec<WalkPath>,
    /// Zero-area triangles dropped while loading.
    pub dropped_triangles: usize,
    /// What loading replaced or ignored in files from other tools (a missing
    /// MTL file or texture, `Kd 1 1 1` lowered, texture options ignored),
    /// each naming the file, for the user to see.
    pub warnings: Vec<String>,
}

/// One rigidly moving mesh with one material.
#[derive(Clone, Debug)]
pub struct Object {
    pub name: String,
    pub mesh: Mesh,
    /// Index into `Scene::materials`.
    pub material: usize,
    pub motion: Motion,
}

/// Object-space triangles as the ray engines take them: positions and
/// indices only, without the texture coordinates shading needs.
#[derive(Clone, Debug, Default)]
pub struct MeshGeometry {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

/// Object-space triangles; `uvs`, when present, has one entry per position.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub uvs: Option<Vec<Vec2>>,
}

impl Mesh {
    /// Total surface area in object space.
    pub fn area(&self) -> f32 {
        self.triangles.iter().map(|&t| self.triangle_area(t)).sum()
    }

    pub fn triangle_area(&self, [a, b, c]: [u32; 3]) -> f32 {
        let (a, b, c) = (
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        );
        0.5 * (b - a).cross(c - a).length()
    }
}

#[derive(Clone, Debug)]
pub struct Material {
    pub name: String,
    pub bsdf: Bsdf,
    pub emission: Option<Emission>,
}

/// Light leaving a surface by itself, uniform over the surface and over
/// directions (a Lambertian emitter).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Emission {
    /// Emitted radiance (W·sr⁻¹·m⁻², linear RGB).
    pub radiance: Vec3,
    /// Whether the back side (against the winding normal) emits too.
    pub two_sided: bool,
}

/// How a surface reflects. Reflectances are linear RGB albedos, each channel
/// in `[0, 1)`; every surface reflects on both sides.
#[derive(Clone, Debug)]
pub enum Bsdf {
    Diffuse {
        reflectance: Vec3,
        /// Multiplies `reflectance` when present (values in `[0, 1)`).
        texture: Option<Arc<Texture>>,
    },
    /// A Lambertian base plus a rough specular lobe without Fresnel; the sum
    /// of the two reflectances stays below one.
    Glossy {
        diffuse: Vec3,
        specular: Vec3,
        /// Microfacet slope roughness `alpha` (GGX) or `alpha` of Ward.
        roughness: f32,
        model: GlossyModel,
    },
    /// Ideal specular reflection.
    Mirror { reflectance: Vec3 },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GlossyModel {
    Ggx,
    Ward,
}

/// Lights that are not surfaces.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// Isotropic point light with radiant intensity (W·sr⁻¹, RGB).
    Point { position: Vec3, intensity: Vec3 },
    /// A distant disk: `direction` points from the scene towards the sun.
    Sun {
        direction: Vec3,
        radiance: Vec3,
        angular_diameter_deg: f32,
    },
}

impl Light {
    /// `1 - cos` of the sun disk's angular radius, through
    /// `1 - cos θ = 2 sin²(θ/2)`: full precision for the sun's tiny cone,
    /// where `cos θ` rounds to 1.
    pub fn sun_one_minus_cos(angular_diameter_deg: f32) -> f32 {
        let s = (0.25 * angular_diameter_deg).to_radians().sin();
        2.0 * s * s
    }

    /// Solid angle of the sun's disk, for converting its radiance to
    /// irradiance.
    pub fn sun_solid_angle(angular_diameter_deg: f32) -> f32 {
        2.0 * std::f32::consts::PI * Self::sun_one_minus_cos(angular_diameter_deg)
    }
}

/// What a point light sends to a surface point, the same for the radiosity
/// solver's direct light and the renderers' light samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointArrival {
    /// Unit direction from the point towards the light.
    pub wi: Vec3,
    /// Intensity over distance squared: the irradiance at normal incidence.
    pub irradiance: Vec3,
    /// From just off the surface (whatever the scene's scale) to the light.
    pub shadow: Ray,
}

impl PointArrival {
    /// Light of a point light at `position` of `intensity` (per steradian)
    /// at `p`, a point of a surface with geometric normal `ng`; `None` at
    /// the light itself or where a value is not finite.
    pub fn new(position: Vec3, intensity: Vec3, p: Vec3, ng: Vec3) -> Option<Self> {
        let d = position - p;
        let dist2 = d.length_squared();
        if dist2.is_nan() || dist2 <= 0.0 {
            return None;
        }
        let wi = d / dist2.sqrt();
        let origin = offset_origin(p, ng, wi);
        Some(Self {
            wi,
            irradiance: intensity / dist2,
            shadow: Ray::segment(origin, position - origin, 1.0),
        })
        .filter(|a| a.wi.is_finite() && a.irradiance.is_finite())
    }
}

/// The animation's time range and frame rate, in seconds and frames/s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Animation {
    pub start: f32,
    pub end: f32,
    pub fps: f32,
}

/// A named viewpoint.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraDesc {
    pub name: String,
    pub position: Vec3,
    /// Unit view direction.
    pub direction: Vec3,
    pub up: Vec3,
    pub vfov_deg: f32,
}

impl CameraDesc {
    /// A perspective camera with this pose and field of view.
    pub fn perspective(&self, width: u32, height: u32) -> Result<Camera> {
        self.with_projection(
            Projection::Perspective {
                vfov_deg: self.vfov_deg,
            },
            width,
            height,
        )
    }

    /// This pose with another projection (fisheye or sphere base views).
    pub fn with_projection(
        &self,
        projection: Projection,
        width: u32,
        height: u32,
    ) -> Result<Camera> {
        Camera::looking(
            self.position,
            self.direction,
            self.up,
            projection,
            width,
            height,
        )
        .map_err(|e| e.context(format!("camera `{}`", self.name)))
    }
}

/// The region the viewer may move in: a segment (1D), an axis-aligned
/// rectangle (2D, one extent zero) or box (3D).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ViewSpace {
    Segment { a: Vec3, b: Vec3 },
    Rectangle { min: Vec3, max: Vec3 },
    Box { min: Vec3, max: Vec3 },
}

impl ViewSpace {
    /// Number of dimensions the viewer may move in.
    pub fn dimensions(&self) -> usize {
        match self {
            ViewSpace::Segment { .. } => 1,
            ViewSpace::Rectangle { .. } => 2,
            ViewSpace::Box { .. } => 3,
        }
    }

    /// The point of the space nearest to `p`: where a viewer who tries to
    /// leave it stops.
    pub fn clamp(&self, p: Vec3) -> Vec3 {
        match *self {
            ViewSpace::Segment { a, b } => {
                let ab = b - a;
                let len2 = ab.length_squared();
                if len2 == 0.0 {
                    return a;
                }
                a + ab * ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
            }
            ViewSpace::Rectangle { min, max } | ViewSpace::Box { min, max } => p.clamp(min, max),
        }
    }

    /// Whether `p` lies in the space, up to [`Self::SLACK`] of its extent:
    /// positions computed on the space's boundary (a path's keys, a
    /// lattice point) land a rounding error outside it.
    pub fn contains(&self, p: Vec3) -> bool {
        p.distance(self.clamp(p)) <= Self::SLACK * self.extent().max(1e-12)
    }

    /// How far outside the space [`Self::contains`] still counts as in,
    /// relative to the space's extent.
    pub const SLACK: f32 = 1e-4;

    /// The longest side: the segment's length, the box's largest edge.
    pub fn extent(&self) -> f32 {
        match *self {
            ViewSpace::Segment { a, b } => (b - a).length(),
            ViewSpace::Rectangle { min, max } | ViewSpace::Box { min, max } => {
                (max - min).max_element()
            }
        }
    }

    /// The lowest and highest corner of the axis-aligned box around the
    /// space.
    pub fn corners(&self) -> (Vec3, Vec3) {
        match *self {
            ViewSpace::Segment { a, b } => (a.min(b), a.max(b)),
            ViewSpace::Rectangle { min, max } | ViewSpace::Box { min, max } => (min, max),
        }
    }

    /// The space as an origin and the edges that span it from there; a
    /// zero edge (the flat side of a rectangle, a degenerate box) is left
    /// out, so there are as many edges as the space has dimensions.
    pub fn edges(&self) -> (Vec3, Vec<Vec3>) {
        let (origin, edges) = match *self {
            ViewSpace::Segment { a, b } => (a, vec![b - a]),
            ViewSpace::Rectangle { min, max } | ViewSpace::Box { min, max } => {
                let d = max - min;
                (min, vec![Vec3::X * d.x, Vec3::Y * d.y, Vec3::Z * d.z])
            }
        };
        (
            origin,
            edges.into_iter().filter(|e| *e != Vec3::ZERO).collect(),
        )
    }

    /// A uniformly distributed point of the space, from numbers uniform in
    /// `[0, 1)` drawn from `next`: one for a segment, three (x, y, z) for a
    /// rectangle or box.
    pub fn sample(&self, mut next: impl FnMut() -> f32) -> Vec3 {
        match *self {
            ViewSpace::Segment { a, b } => a.lerp(b, next()),
            ViewSpace::Rectangle { min, max } | ViewSpace::Box { min, max } => {
                min + (max - min) * Vec3::new(next(), next(), next())
            }
        }
    }
}

/// A segment view space written `x,y,z:x,y,z` (the `--view-segment` of
/// the commands that replace a scene's view space).
pub fn parse_segment(s: &str) -> Result<ViewSpace, String> {
    let err = |why: &str| format!("`{s}` is not a segment x,y,z:x,y,z ({why})");
    let point = |p: &str| -> Result<Vec3, String> {
        let v: Vec<f32> = p
            .split(',')
            .map(|c| c.trim().parse::<f32>())
            .collect::<Result<_, _>>()
            .map_err(|e| err(&format!("`{p}`: {e}")))?;
        match v[..] {
            [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vec3::new(x, y, z)),
            _ => Err(err(&format!("`{p}` is not three finite numbers"))),
        }
    };
    let (a, b) = s.split_once(':').ok_or_else(|| err("no `:`"))?;
    Ok(ViewSpace::Segment {
        a: point(a)?,
        b: point(b)?,
    })
}

/// A camera moving over time: keyframes interpolated linearly.
#[derive(Clone, Debug, PartialEq)]
pub struct WalkPath {
    pub name: String,
    pub keys: Vec<PathKey>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathKey {
    pub time: f32,
    pub position: Vec3,
    pub direction: Vec3,
    pub up: Vec3,
    pub vfov_deg: f32,
}

impl WalkPath {
    /// The times of the first and last keys.
    pub fn span(&self) -> (f32, f32) {
        match (self.keys.first(), self.keys.last()) {
            (Some(a), Some(b)) => (a.time, b.time),
            _ => (0.0, 0.0),
        }
    }

    /// The viewer at time `t`: keys interpolated linearly (directions
    /// renormalized), held before the first key and after the last.
    pub fn at(&self, t: f32) -> CameraDesc {
        let i = self.keys.partition_point(|k| k.time <= t);
        let (a, b, s) = match (i, self.keys.len()) {
            (_, 1) | (0, _) => (self.keys[0], self.keys[0], 0.0),
            (i, n) if i == n => (self.keys[n - 1], self.keys[n - 1], 0.0),
            (i, _) => {
                let (a, b) = (self.keys[i - 1], self.keys[i]);
                (a, b, (t - a.time) / (b.time - a.time))
            }
        };
        let direction = a.direction.lerp(b.direction, s).normalize_or_zero();
        CameraDesc {
            name: format!("{}@{t}", self.name),
            position: a.position.lerp(b.position, s),
            direction: if direction == Vec3::ZERO {
                a.direction
            } else {
                direction
            },
            up: a.up.lerp(b.up, s).normalize_or_zero(),
            vfov_deg: a.vfov_deg + (b.vfov_deg - a.vfov_deg) * s,
        }
    }
}

impl Scene {
    /// The walk path named `name`.
    pub fn path(&self, name: &str) -> Result<&WalkPath> {
        let names = self.paths.iter().map(|p| p.name.as_str());
        self.paths
            .iter()
            .find(|p| p.name == name)
            .ok_or_else(|| self.unknown("path", name, names))
    }

    /// The error for a name the scene does not define, listing those it does.
    fn unknown<'a>(
        &self,
        what: &str,
        name: &str,
        known: impl Iterator<Item = &'a str>,
    ) -> anyhow::Error {
        let known: Vec<&str> = known.collect();
        anyhow!(
            "{}: no {what} named `{name}` ({what}s: {})",
            self.source.display(),
            if known.is_empty() {
                "none".to_string()
            } else {
                known.join(", ")
            }
        )
    }

    /// Reads and validates `scene.toml` and the meshes it names.
    pub fn load(path: impl Into<PathBuf>) -> Result<Scene> {
        load::load(path.into())
    }

    /// Checks a time given from outside (a command's `--time`, a C call, a
    /// frame to synthesize): finite and, for an animated scene, within the
    /// animation. Outside it [`Scene::at`] holds the end poses and a bake
    /// has no images, so such a time would show another time's scene under
    /// its own name. A static scene looks the same at every time, and its
    /// walk paths' keys (camera times) may span any range, so every finite
    /// time is one of its times.
    pub fn check_time(&self, t: f32) -> Result<()> {
        ensure!(t.is_finite(), "time {t} is not a number");
        let a = self.animation;
        ensure!(
            self.is_static() || (a.start..=a.end).contains(&t),
            "time {t} s lies outside the animation of {}, [{}, {}] s: give a time in that range",
            self.source.display(),
            a.start,
            a.end
        );
        Ok(())
    }

    /// Every object's object-to-world transform at time `t`, in object
    /// order; before the animation's keys the first pose, after them the
    /// last (times from outside are checked by [`Scene::check_time`]).
    pub fn at(&self, t: f32) -> Vec<Affine3A> {
        self.objects.iter().map(|o| o.motion.pose(t)).collect()
    }

    /// The object-space meshes as the ray engines take them.
    pub fn geometry(&self) -> Vec<MeshGeometry> {
        self.objects
            .iter()
            .map(|o| MeshGeometry {
                positions: o.mesh.positions.clone(),
                triangles: o.mesh.triangles.clone(),
            })
            .collect()
    }

    pub fn camera(&self, name: &str) -> Result<&CameraDesc> {
        let names = self.cameras.iter().map(|c| c.name.as_str());
        self.cameras
            .iter()
            .find(|c| c.name == name)
            .ok_or_else(|| self.unknown("camera", name, names))
    }

    pub fn material_of(&self, object: u32) -> &Material {
        &self.materials[self.objects[object as usize].material]
    }

    /// Whether anything moves: a static scene needs a single time sample.
    pub fn is_static(&self) -> bool {
        self.objects.iter().all(|o| o.motion.is_static())
    }

    /// Whether any surface is glossy or a mirror: otherwise no specular rays
    /// are needed.
    pub fn has_specular(&self) -> bool {
        self.materials
            .iter()
            .any(|m| !matches!(m.bsdf, Bsdf::Diffuse { .. }))
    }

    /// Axis-aligned bounds of the whole scene at time `t`.
    pub fn bounds(&self, t: f32) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for (o, xf) in self.objects.iter().zip(self.at(t)) {
            for &p in &o.mesh.positions {
                let w = xf.transform_point3(p);
                lo = lo.min(w);
                hi = hi.max(w);
            }
        }
        (lo, hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_view_space_clamps_contains_and_samples_its_own_points() {
        let seg = ViewSpace::Segment {
            a: Vec3::new(0.0, 1.0, 0.0),
            b: Vec3::new(4.0, 1.0, 0.0),
        };
        let rect = ViewSpace::Rectangle {
            min: Vec3::new(-1.0, 1.0, -2.0),
            max: Vec3::new(1.0, 1.0, 2.0),
        };
        let bx = ViewSpace::Box {
            min: Vec3::ZERO,
            max: Vec3::new(1.0, 2.0, 3.0),
        };
        // Nearest points: onto the segment's line within its ends, into the box.
        assert_eq!(
            seg.clamp(Vec3::new(2.0, 5.0, 3.0)),
            Vec3::new(2.0, 1.0, 0.0)
        );
        assert_eq!(
            seg.clamp(Vec3::new(-3.0, 1.0, 0.0)),
            Vec3::new(0.0, 1.0, 0.0)
        );
        assert_eq!(
            rect.clamp(Vec3::new(5.0, 0.0, 0.0)),
            Vec3::new(1.0, 1.0, 0.0)
        );
        assert_eq!((seg.extent(), rect.extent(), bx.extent()), (4.0, 4.0, 3.0));
        assert_eq!(
            seg.corners(),
            (Vec3::new(0.0, 1.0, 0.0), Vec3::new(4.0, 1.0, 0.0))
        );
        // As many edges as dimensions: the rectangle's flat y is none.
        for s in [seg, rect, bx] {
            assert_eq!(s.edges().1.len(), s.dimensions(), "{s:?}");
        }
        // Inside, on the boundary and a rounding error beyond it count; a
        // step of a thousandth of the extent outside does not.
        assert!(seg.contains(Vec3::new(4.0, 1.0, 0.0)));
        assert!(seg.contains(Vec3::new(4.0 + 1e-5, 1.0, 0.0)));
        assert!(!seg.contains(Vec3::new(4.0 + 4e-3, 1.0, 0.0)));
        assert!(!rect.contains(Vec3::new(0.0, 1.01, 0.0)));
        let mut u = [0.25f32, 0.5, 0.75].into_iter().cycle();
        for s in [seg, rect, bx] {
            let p = s.sample(|| u.next().unwrap());
            assert!(s.contains(p), "{s:?}: {p}");
        }
        // One number for a segment: at 0.25 of the way from a.
        assert_eq!(seg.sample(|| 0.25), Vec3::new(1.0, 1.0, 0.0));
    }

    #[test]
    fn a_point_light_arrives_as_intensity_over_distance_squared_with_a_shadow_ray_to_it() {
        for scale in [1e-4f32, 1.0, 1e4] {
            let light = Vec3::new(0.0, 2.0, 0.0) * scale;
            let p = Vec3::new(1.5, 0.0, 0.0) * scale;
            let a = PointArrival::new(light, Vec3::splat(10.0), p, Vec3::Y).unwrap();
            let d2 = (light - p).length_squared();
            assert!((a.irradiance.x * d2 / 10.0 - 1.0).abs() < 1e-5, "{scale}");
            assert!((a.wi - (light - p) / d2.sqrt()).length() < 1e-6);
            // The shadow ray starts just above the surface and ends at the light.
            assert!(a.shadow.origin.y > p.y);
            assert!((a.shadow.at(a.shadow.tmax) - light).length() <= 1e-5 * scale);
        }
        // At the light itself, or from a NaN point, nothing arrives.
        assert!(PointArrival::new(Vec3::ONE, Vec3::ONE, Vec3::ONE, Vec3::Y).is_none());
        assert!(PointArrival::new(Vec3::ONE, Vec3::ONE, Vec3::NAN, Vec3::Y).is_none());
    }

    #[test]
    fn the_suns_solid_angle_keeps_its_precision_for_a_tiny_disk() {
        // 2π(1 - cos θ) for the sun's 0.53° disk, in double precision.
        let half = (0.53f64 / 2.0).to_radians();
        let exact = 2.0 * std::f64::consts::PI * (1.0 - half.cos());
        let ours = f64::from(Light::sun_solid_angle(0.53));
        assert!((ours / exact - 1.0).abs() < 1e-5, "{ours} against {exact}");
    }
}
