//! The content of an image file independent of the library that writes it:
//! named channel planes plus header attributes. Both EXR back ends (OpenImageIO
//! and the `exr` crate) only move [`Planes`] to and from disk, so the channel
//! names, sample types and metadata of a range image are decided once, here,
//! and files written by one back end read identically with the other.

use std::path::Path;

use anyhow::{anyhow, bail, ensure, Context, Result};
use glam::Vec3;

use super::color::srgb_decode;
use super::Texture;
use super::{RangeImage, RangeMeta};
use crate::camera::{Camera, Projection, Window};
use crate::checksum::Fnv;

/// One channel's samples, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub enum Plane {
    F32(Vec<f32>),
    U32(Vec<u32>),
}

impl Plane {
    fn len(&self) -> usize {
        match self {
            Plane::F32(v) => v.len(),
            Plane::U32(v) => v.len(),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum Attr {
    Float(f32),
    Vector([f32; 3]),
    Text(String),
}

/// Where a file's pixels (its EXR data window) lie in the image they are
/// part of (its display window): the data window's corner relative to the
/// display window's, and the display window's size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DataWindow {
    pub x: i64,
    pub y: i64,
    pub full_width: u64,
    pub full_height: u64,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Planes {
    /// The size of the pixels held: the data window's.
    pub width: u32,
    pub height: u32,
    /// `None` where the data window is the display window.
    pub window: Option<DataWindow>,
    pub channels: Vec<(String, Plane)>,
    pub attributes: Vec<(String, Attr)>,
}

// The distance channel is not called `Z`: it is measured along each pixel's
// ray, while `Z` conventionally holds depth along the view axis.
const RADIANCE: [&str; 3] = ["R", "G", "B"];
const DISTANCE: &str = "distance";
const OBJECT_ID: &str = "object_id";
const PRIMITIVE_ID: &str = "primitive_id";
const NORMAL: [&str; 3] = ["N.x", "N.y", "N.z"];

// Camera poses are stored as float vectors, not derived from one another, so
// a camera read back compares equal bit for bit to the one written.
const POSITION: &str = "rangewalk:cameraPosition";
const FORWARD: &str = "rangewalk:cameraForward";
const UP: &str = "rangewalk:cameraUp";
const RIGHT: &str = "rangewalk:cameraRight";
const PROJECTION: &str = "rangewalk:projection";
const VFOV: &str = "rangewalk:vfovDegrees";
const TIME: &str = "rangewalk:time";
const SCENE: &str = "rangewalk:scene";

fn split(v: &[Vec3]) -> [Vec<f32>; 3] {
    [
        v.iter().map(|p| p.x).collect(),
        v.iter().map(|p| p.y).collect(),
        v.iter().map(|p| p.z).collect(),
    ]
}

/// `values` gathered into a new plane by `f`, or an error saying what the
/// copy of a `w`×`h` image for writing needs where memory is short (a
/// frame as large as memory allows has no room for a second copy).
fn gathered<T, U>(values: &[T], f: impl Fn(&T) -> U, (w, h): (u32, u32)) -> Result<Vec<U>> {
    let mut plane = Vec::new();
    crate::alloc::reserve(&mut plane, values.len(), || {
        format!("a plane of the {w}x{h} range image's copy for writing")
    })?;
    plane.extend(values.iter().map(f));
    Ok(plane)
}

impl Planes {
    /// The channels and metadata of a range image; fails when the image's
    /// per-pixel vectors or its camera disagree with its size.
    pub fn from_range(image: &RangeImage) -> Result<Planes> {
        let n = image.len();
        let (w, h) = (image.width, image.height);
        ensure!(n > 0, "range image {w}x{h} has no pixels");
        for (what, len) in [
            ("radiance", image.radiance.len()),
            ("distance", image.distance.len()),
            ("object_id", image.object_id.len()),
            ("primitive_id", image.primitive_id.len()),
            ("normal", image.normal.len()),
        ] {
            ensure!(
                len == n,
                "range image {w}x{h}: `{what}` has {len} values, expected {n}"
            );
        }
        let cam = &image.meta.camera;
        ensure!(
            (cam.width, cam.height) == (w, h),
            "range image {w}x{h} has a {}x{} camera",
            cam.width,
            cam.height
        );

        let size = (w, h);
        let xyz: [fn(&Vec3) -> f32; 3] = [|v| v.x, |v| v.y, |v| v.z];
        let mut channels = Vec::with_capacity(9);
        for (name, f) in RADIANCE.iter().zip(xyz) {
            let plane = gathered(&image.radiance, f, size)?;
            channels.push((name.to_string(), Plane::F32(plane)));
        }
        let distance = gathered(&image.distance, |&d| d, size)?;
        channels.push((DISTANCE.into(), Plane::F32(distance)));
        let objects = gathered(&image.object_id, |&o| o, size)?;
        channels.push((OBJECT_ID.into(), Plane::U32(objects)));
        let primitives = gathered(&image.primitive_id, |&p| p, size)?;
        channels.push((PRIMITIVE_ID.into(), Plane::U32(primitives)));
        for (name, f) in NORMAL.iter().zip(xyz) {
            let plane = gathered(&image.normal, f, size)?;
            channels.push((name.to_string(), Plane::F32(plane)));
        }

        let mut attributes = vec![
            (POSITION.into(), Attr::Vector(cam.position.into())),
            (FORWARD.into(), Attr::Vector(cam.forward.into())),
            (UP.into(), Attr::Vector(cam.up.into())),
            (RIGHT.into(), Attr::Vector(cam.right.into())),
            (PROJECTION.into(), Attr::Text(cam.projection.name().into())),
            (TIME.into(), Attr::Float(image.meta.time)),
            (SCENE.into(), Attr::Text(image.meta.scene.clone())),
        ];
        if let Projection::Perspective { vfov_deg } = cam.projection {
            attributes.push((VFOV.into(), Attr::Float(vfov_deg)));
        }
        let window = cam.window.map(|v| DataWindow {
            x: v.x.into(),
            y: v.y.into(),
            full_width: v.full_width.into(),
            full_height: v.full_height.into(),
        });
        Ok(Planes {
            width: w,
            height: h,
            window,
            channels,
            attributes,
        })
    }

    /// The camera window the data window gives: it must lie inside the
    /// display window, which is the projection's whole size.
    fn camera_window(&self) -> Result<Option<Window>> {
        let Some(d) = self.window else {
            return Ok(None);
        };
        let (w, h) = (self.width, self.height);
        let fits = |v: i64| u32::try_from(v).ok();
        let (Some(x), Some(y), Some(full_width), Some(full_height)) = (
            fits(d.x),
            fits(d.y),
            u32::try_from(d.full_width).ok(),
            u32::try_from(d.full_height).ok(),
        ) else {
            bail!(
                "EXR `dataWindow` ({w}x{h} at ({}, {}) of the `displayWindow`) lies outside the {}x{} `displayWindow`",
                d.x,
                d.y,
                d.full_width,
                d.full_height
            );
        };
        let window = Window {
            x,
            y,
            full_width,
            full_height,
        };
        window
            .check(w, h)
            .map_err(|e| anyhow!("EXR `dataWindow` does not fit its `displayWindow`: {e}"))?;
        Ok(Some(window))
    }

    /// The range image these planes hold; fails naming the first channel or
    /// attribute that is missing or malformed.
    pub fn into_range(self) -> Result<RangeImage> {
        let camera = Camera {
            position: self.vector(POSITION)?,
            forward: self.vector(FORWARD)?,
            up: self.vector(UP)?,
            right: self.vector(RIGHT)?,
            projection: match self.text(PROJECTION)? {
                "perspective" => Projection::Perspective {
                    vfov_deg: self.float(VFOV)?,
                },
                "fisheye" => Projection::Fisheye,
                "sphere" => Projection::Sphere,
                other => bail!("attribute {PROJECTION} has unknown projection `{other}`"),
            },
            width: self.width,
            height: self.height,
            window: self.camera_window()?,
        };
        let meta = RangeMeta {
            camera,
            time: self.float(TIME)?,
            scene: self.text(SCENE)?.to_string(),
        };
        let [r, g, b] = RADIANCE.map(|name| self.f32_plane(name));
        let [nx, ny, nz] = NORMAL.map(|name| self.f32_plane(name));
        let join = |x: &[f32], y: &[f32], z: &[f32]| -> Vec<Vec3> {
            (0..x.len()).map(|i| Vec3::new(x[i], y[i], z[i])).collect()
        };
        Ok(RangeImage {
            width: self.width,
            height: self.height,
            radiance: join(r?, g?, b?),
            distance: self.f32_plane(DISTANCE)?.to_vec(),
            object_id: self.u32_plane(OBJECT_ID)?.to_vec(),
            primitive_id: self.u32_plane(PRIMITIVE_ID)?.to_vec(),
            normal: join(nx?, ny?, nz?),
            meta,
        })
    }

    /// Drops every channel [`Planes::into_range`] does not read (the light
    /// layers), so that a reader that has taken what it wants of them does
    /// not hold them beside the range image being made.
    pub fn keep_range_channels(&mut self) {
        self.channels.retain(|(name, _)| {
            let n = name.as_str();
            RADIANCE.contains(&n)
                || NORMAL.contains(&n)
                || [DISTANCE, OBJECT_ID, PRIMITIVE_ID].contains(&n)
        });
    }

    /// Adds an RGB layer as channels `<name>.R`, `<name>.G`, `<name>.B`.
    pub fn push_rgb(&mut self, name: &str, values: &[Vec3]) -> Result<()> {
        let n = self.width as usize * self.height as usize;
        ensure!(
            values.len() == n,
            "layer `{name}` has {} values for {n} pixels",
            values.len()
        );
        for (c, plane) in RADIANCE.iter().zip(split(values)) {
            self.channels
                .push((format!("{name}.{c}"), Plane::F32(plane)));
        }
        Ok(())
    }

    /// The RGB layer added by [`Planes::push_rgb`].
    pub fn rgb(&self, name: &str) -> Result<Vec<Vec3>> {
        let [r, g, b] = RADIANCE.map(|c| self.f32_plane(&format!("{name}.{c}")));
        let (r, g, b) = (r?, g?, b?);
        Ok((0..r.len()).map(|i| Vec3::new(r[i], g[i], b[i])).collect())
    }

    /// A hash of what the planes hold: every channel's name and samples and
    /// every `rangewalk:*` attribute, in name order. It does not depend on
    /// how a file encodes them (the order of header attributes, which the
    /// `exr` crate leaves to a hash map; what a library adds on its own), so
    /// the same image has the same hash written by either back end.
    pub fn content_hash(&self) -> u64 {
        let mut h = Fnv::default();
        h.write(&self.width.to_le_bytes());
        h.write(&self.height.to_le_bytes());
        // Only where there is one, so that whole images hash as they did
        // before files had windows.
        if let Some(d) = self.window {
            h.write(b"window");
            for v in [d.x, d.y, d.full_width as i64, d.full_height as i64] {
                h.write(&v.to_le_bytes());
            }
        }
        let mut channels: Vec<&(String, Plane)> = self.channels.iter().collect();
        channels.sort_by(|a, b| a.0.cmp(&b.0));
        for (name, plane) in channels {
            h.write(name.as_bytes());
            match plane {
                Plane::F32(v) => {
                    h.write(b"f");
                    v.iter().for_each(|x| h.write(&x.to_le_bytes()));
                }
                Plane::U32(v) => {
                    h.write(b"u");
                    v.iter().for_each(|x| h.write(&x.to_le_bytes()));
                }
            }
        }
        let mut attributes: Vec<&(String, Attr)> = self
            .attributes
            .iter()
            .filter(|(n, _)| n.starts_with("rangewalk:"))
            .collect();
        attributes.sort_by(|a, b| a.0.cmp(&b.0));
        for (name, attr) in attributes {
            h.write(name.as_bytes());
            match attr {
                Attr::Float(x) => h.write(&x.to_le_bytes()),
                Attr::Vector(v) => v.iter().for_each(|x| h.write(&x.to_le_bytes())),
                Attr::Text(t) => h.write(t.as_bytes()),
            }
        }
        h.finish()
    }

    /// The named channel, checked to hold one sample per pixel.
    pub fn channel(&self, name: &str) -> Result<&Plane> {
        let (_, plane) = self
            .channels
            .iter()
            .find(|(n, _)| n == name)
            .ok_or_else(|| {
                let names: Vec<&str> = self.channels.iter().map(|(n, _)| n.as_str()).collect();
                anyhow!("no channel `{name}` (channels: {})", names.join(", "))
            })?;
        let n = self.width as usize * self.height as usize;
        ensure!(
            plane.len() == n,
            "channel `{name}` has {} samples for {n} pixels",
            plane.len()
        );
        Ok(plane)
    }

    fn f32_plane(&self, name: &str) -> Result<&[f32]> {
        match self.channel(name)? {
            Plane::F32(v) => Ok(v),
            Plane::U32(_) => bail!("channel `{name}` holds integers, expected floats"),
        }
    }

    fn u32_plane(&self, name: &str) -> Result<&[u32]> {
        match self.channel(name)? {
            Plane::U32(v) => Ok(v),
            Plane::F32(_) => bail!("channel `{name}` holds floats, expected 32-bit unsigned ids"),
        }
    }

    fn attribute(&self, name: &str) -> Result<&Attr> {
        self.attributes
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, a)| a)
            .with_context(|| format!("no attribute {name} (not a rangewalk range image?)"))
    }

    fn vector(&self, name: &str) -> Result<Vec3> {
        match self.attribute(name)? {
            Attr::Vector(v) => Ok(Vec3::from(*v)),
            other => bail!("attribute {name} is {other:?}, expected a float 3-vector"),
        }
    }

    fn float(&self, name: &str) -> Result<f32> {
        match self.attribute(name)? {
            Attr::Float(x) => Ok(*x),
            other => bail!("attribute {name} is {other:?}, expected a float"),
        }
    }

    fn text(&self, name: &str) -> Result<&str> {
        match self.attribute(name)? {
            Attr::Text(s) => Ok(s),
            other => bail!("attribute {name} is {other:?}, expected a string"),
        }
    }
}

impl Planes {
    /// A linear-RGB texture from the `R`, `G`, `B` channels, or from a grey
    /// `Y` or lone first channel; `srgb` says the samples are sRGB-encoded.
    pub fn into_texture(self, path: &Path, srgb: bool) -> Result<Texture> {
        let names: Vec<&str> = self.channels.iter().map(|(n, _)| n.as_str()).collect();
        let pick: [&str; 3] = if ["R", "G", "B"].iter().all(|c| names.contains(c)) {
            ["R", "G", "B"]
        } else if names.contains(&"Y") {
            ["Y"; 3]
        } else if (1..=2).contains(&names.len()) {
            [names[0]; 3]
        } else {
            bail!(
                "{}: no R, G, B or grey channel for a texture (channels: {})",
                path.display(),
                names.join(", ")
            );
        };
        let [r, g, b] = pick.map(|name| self.f32_plane(name));
        let (r, g, b) = (r?, g?, b?);
        let decode = |x: f32| if srgb { srgb_decode(x) } else { x };
        let texels = (0..r.len())
            .map(|i| Vec3::new(decode(r[i]), decode(g[i]), decode(b[i])))
            .collect();
        Ok(Texture {
            source: path.to_path_buf(),
            width: self.width,
            height: self.height,
            texels,
        })
    }
}
