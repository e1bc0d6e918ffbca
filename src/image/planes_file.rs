//! What synthesis keeps of a base image, stored beside its EXR, so that
//! synthesis opens a base without decoding the EXR: decoding and hashing a
//! base's EXR (eighteen ZIP-compressed channels, the light layers among
//! them) took most of a second for a 2,544² sphere's window, while reading
//! this file takes tens of milliseconds.
//!
//! The file (version 3) holds what a base reads ([`BasePlanes`]: radiance
//! as scaled half floats, distance, object and primitive ids, normals; not
//! the light layers, which re-shading does not read), each plane cut into
//! chunks of [`CHUNK`] pixels. A chunk is its pixels' little-endian words
//! (2 bytes for half floats, else 4) with their bytes regrouped (every
//! word's first byte, then every second byte, ...: the sign and exponent
//! bytes of neighbouring floats are alike, their low mantissa bytes are
//! noise), compressed as one zstd frame. Each chunk stands alone: it is
//! found from the header's table of chunk lengths, checked against its
//! FNV-1a 64 before it is decoded and decoded without any other, and the
//! chunks are read on all cores at once. The header holds the camera
//! (floats as bit patterns, so it reads back bit for bit), the chunks'
//! lengths and checksums and the content checksum of the EXR the planes
//! were made with; it is followed by its own checksum. A reader that holds
//! the EXR's checksum (the bake's manifest) therefore trusts every byte it
//! reads: header, then chunks.
//!
//! ```text
//! "RWPLANES"  u32 LE header length L  header (JSON, L bytes)  FNV-1a 64 of the header (16 hex digits)
//! the chunks of plane 0 (radiance_half, 3 half floats a pixel), then of plane 1 (distance),
//! 2 (object_id), 3 (primitive_id), 4 (normal, 3), each as long as the header says
//! ```
//!
//! Versions 1 and 2 (bakes of manifest versions 6 and 7) hold the range
//! image whole: radiance (3 32-bit words), distance, object_id,
//! primitive_id, normal (3); version 1 stored the words raw, unregrouped
//! and uncompressed, with no lengths in the header. Both are still read
//! ([`read`]).

use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::ops::Range;
use std::os::unix::fs::FileExt;
use std::path::Path;

use anyhow::{anyhow, bail, ensure, Context, Result};
use glam::Vec3;
use half::f16;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{write_atomically, RangeImage, RangeMeta, MAX_PIXELS};
use crate::camera::{Camera, Projection, Window};
use crate::checksum::{fnv1a64, hex, Fnv};

const MAGIC: &[u8; 8] = b"RWPLANES";
/// The layout's version, in the header.
pub const VERSION: u32 = 3;
/// The zstd level chunks are written at: on base images' noisy radiance
/// the higher levels save a few percent of bytes and cost several times
/// the time (see the bake format's documentation for the figures).
const LEVEL: i32 = 1;
/// Pixels per chunk: small enough that a window's chunks keep both cores
/// busy, large enough that the header's table of checksums stays short.
pub const CHUNK: usize = 1 << 16;
/// The largest header accepted: a header names its chunks' lengths and
/// checksums, some 30 bytes each, so even an 8,192² image needs well
/// under this.
const MAX_HEADER: u32 = 16 << 20;

/// The planes of versions 1 and 2 in file order, with their 32-bit words
/// per pixel.
const PLANES: [(&str, usize); 5] = [
    ("radiance", 3),
    ("distance", 1),
    ("object_id", 1),
    ("primitive_id", 1),
    ("normal", 3),
];

/// The planes of version 3 in file order, with their words per pixel:
/// what synthesis keeps of a base, radiance as half floats (16-bit words),
/// the rest 32-bit words.
const BASE_PLANES: [(&str, usize); 5] = [
    ("radiance_half", 3),
    ("distance", 1),
    ("object_id", 1),
    ("primitive_id", 1),
    ("normal", 3),
];

/// Bytes of a word of plane `p` in a file of `version`.
fn word_bytes(version: u32, p: usize) -> usize {
    if version >= 3 && p == 0 {
        2
    } else {
        4
    }
}

fn layout(version: u32) -> &'static [(&'static str, usize)] {
    if version >= 3 {
        &BASE_PLANES
    } else {
        &PLANES
    }
}

/// What synthesis reads of a base image (`synth::Base`), as a version-3
/// planes file holds it: radiance divided by `scale` into half floats, as
/// the base keeps it, each pixel's distance, ids and normal (synthesis
/// re-lights pixels beside the lights from neighbours of like normal). A
/// base made from the EXR goes through [`BasePlanes::of`] too, so both are
/// the same bit for bit.
#[derive(Clone, Debug, PartialEq)]
pub struct BasePlanes {
    pub width: u32,
    pub height: u32,
    /// Radiance divided by `scale`.
    pub radiance: Vec<[f16; 3]>,
    /// A power of two (see `synth::Base::scale`).
    pub scale: f32,
    pub distance: Vec<f32>,
    pub object_id: Vec<u32>,
    pub primitive_id: Vec<u32>,
    pub normal: Vec<Vec3>,
    pub meta: RangeMeta,
}

/// A power of two that brings the brightest finite radiance within
/// half-float range (which reaches 65504), with a factor two of headroom,
/// whatever the scene's intensities. Version-3 planes files hold halves
/// made with it: a change to it must move [`VERSION`], or their bases
/// would differ from their EXRs'.
pub fn radiance_scale(radiance: &[Vec3]) -> f32 {
    let brightest = radiance
        .par_iter()
        .map(|c| if c.is_finite() { c.max_element() } else { 0.0 })
        .reduce(|| 0.0, f32::max);
    if brightest > 0.0 {
        2f32.powi((brightest / 32768.0).log2().ceil() as i32)
    } else {
        1.0
    }
}

/// Radiance `c` times `inv_scale` in half floats, negative values as zero.
pub fn to_half(c: Vec3, inv_scale: f32) -> [f16; 3] {
    let c = (c * inv_scale).max(Vec3::ZERO);
    [f16::from_f32(c.x), f16::from_f32(c.y), f16::from_f32(c.z)]
}

impl BasePlanes {
    /// What a base reads of `image`: its radiance scaled
    /// ([`radiance_scale`]) into half floats, the rest as it is.
    pub fn of(image: RangeImage) -> BasePlanes {
        let scale = radiance_scale(&image.radiance);
        let inv = 1.0 / scale;
        let radiance = image
            .radiance
            .par_iter()
            .map(|&c| to_half(c, inv))
            .collect();
        BasePlanes {
            width: image.width,
            height: image.height,
            radiance,
            scale,
            distance: image.distance,
            object_id: image.object_id,
            primitive_id: image.primitive_id,
            normal: image.normal,
            meta: image.meta,
        }
    }

    pub fn len(&self) -> usize {
        self.width as usize * self.height as usize
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[derive(Debug, Serialize, Deserialize)]
struct Header {
    version: u32,
    width: u32,
    height: u32,
    camera: CameraBits,
    /// Scene time, as the bits of an `f32`.
    time: u32,
    scene: String,
    /// The content checksum (`image::exr_content_hash`, 16 hex digits) of
    /// the EXR these planes were written with.
    image_fnv1a64: String,
    chunk_pixels: usize,
    /// The radiance's scale, as the bits of an `f32` (version 3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    scale: Option<u32>,
    planes: Vec<PlaneRecord>,
}

/// A camera with its floats as bit patterns: JSON numbers go through
/// decimal, and a base's camera must read back bit for bit.
#[derive(Debug, Serialize, Deserialize)]
struct CameraBits {
    position: [u32; 3],
    forward: [u32; 3],
    up: [u32; 3],
    right: [u32; 3],
    projection: String,
    vfov_deg: Option<u32>,
    window: Option<Window>,
}

#[derive(Debug, Serialize, Deserialize)]
struct PlaneRecord {
    name: String,
    words_per_pixel: usize,
    /// FNV-1a 64 of each chunk's bytes as they lie in the file, 16 hex
    /// digits.
    chunks: Vec<String>,
    /// Each chunk's length in the file (bytes); absent in version 1, whose
    /// chunks are the raw words.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    bytes: Vec<u64>,
}

fn bits(v: Vec3) -> [u32; 3] {
    v.to_array().map(f32::to_bits)
}

fn vec3(b: [u32; 3]) -> Vec3 {
    Vec3::from_array(b.map(f32::from_bits))
}

impl CameraBits {
    fn of(c: &Camera) -> CameraBits {
        CameraBits {
            position: bits(c.position),
            forward: bits(c.forward),
            up: bits(c.up),
            right: bits(c.right),
            projection: c.projection.name().into(),
            vfov_deg: match c.projection {
                Projection::Perspective { vfov_deg } => Some(vfov_deg.to_bits()),
                _ => None,
            },
            window: c.window,
        }
    }

    fn camera(&self, width: u32, height: u32) -> Result<Camera> {
        let projection = match (self.projection.as_str(), self.vfov_deg) {
            ("perspective", Some(v)) => Projection::Perspective {
                vfov_deg: f32::from_bits(v),
            },
            ("fisheye", None) => Projection::Fisheye,
            ("sphere", None) => Projection::Sphere,
            (p, v) => bail!("`camera.projection` `{p}` with `vfov_deg` {v:?} is no projection"),
        };
        if let Some(w) = self.window {
            w.check(width, height)
                .map_err(|e| anyhow!("`camera.window`: {e}"))?;
        }
        Ok(Camera {
            position: vec3(self.position),
            forward: vec3(self.forward),
            up: vec3(self.up),
            right: vec3(self.right),
            projection,
            width,
            height,
            window: self.window,
        })
    }
}

/// Plane `p`'s words of pixels `range`, as little-endian bytes.
fn plane_bytes(image: &RangeImage, p: usize, range: Range<usize>) -> Vec<u8> {
    let mut out = Vec::with_capacity(range.len() * PLANES[p].1 * 4);
    let mut put = |w: u32| out.extend_from_slice(&w.to_le_bytes());
    match p {
        0 | 4 => {
            let v = if p == 0 {
                &image.radiance
            } else {
                &image.normal
            };
            for x in v[range].iter().flat_map(|c| c.to_array()) {
                put(x.to_bits());
            }
        }
        1 => image.distance[range].iter().for_each(|d| put(d.to_bits())),
        2 => image.object_id[range].iter().for_each(|&o| put(o)),
        _ => image.primitive_id[range].iter().for_each(|&o| put(o)),
    }
    out
}

fn chunks(n: usize) -> impl Iterator<Item = Range<usize>> + Clone {
    (0..n.div_ceil(CHUNK)).map(move |c| c * CHUNK..((c + 1) * CHUNK).min(n))
}

/// The bytes of `size`-byte words regrouped: every word's byte 0, then
/// every byte 1, and so on.
fn regroup(words: &[u8], size: usize) -> Vec<u8> {
    let n = words.len() / size;
    let mut out = vec![0u8; words.len()];
    for (i, w) in words.chunks_exact(size).enumerate() {
        for (k, &b) in w.iter().enumerate() {
            out[k * n + i] = b;
        }
    }
    out
}

/// The inverse of [`regroup`].
fn ungroup(grouped: &[u8], size: usize) -> Vec<u8> {
    let n = grouped.len() / size;
    let mut out = vec![0u8; grouped.len()];
    for (i, w) in out.chunks_exact_mut(size).enumerate() {
        for (k, b) in w.iter_mut().enumerate() {
            *b = grouped[k * n + i];
        }
    }
    out
}

/// Writes `image`'s planes whole to `path` (atomically) as a version-2
/// file, naming `image_sum`, the content checksum of the EXR written with
/// them. Bakes write [`write_base`]'s files; this writer is kept for
/// comparing the two.
pub fn write(path: &Path, image: &RangeImage, image_sum: &str) -> Result<()> {
    let n = image.len();
    let lens = [
        image.radiance.len(),
        image.distance.len(),
        image.object_id.len(),
        image.primitive_id.len(),
        image.normal.len(),
    ];
    ensure!(
        n > 0 && lens.iter().all(|&l| l == n),
        "writing {}: a {}x{} range image with planes of {lens:?} values",
        path.display(),
        image.width,
        image.height
    );
    let layout = Layout {
        version: 2,
        width: image.width,
        height: image.height,
        meta: &image.meta,
        scale: None,
    };
    write_planes(path, layout, image_sum, |p, r| plane_bytes(image, p, r))
}

/// Writes what synthesis keeps of a base to `path` (atomically) as a
/// version-3 file, naming `image_sum`, the content checksum of the EXR
/// written beside it.
pub fn write_base(path: &Path, base: &BasePlanes, image_sum: &str) -> Result<()> {
    let n = base.len();
    let lens = [
        base.radiance.len(),
        base.distance.len(),
        base.object_id.len(),
        base.primitive_id.len(),
        base.normal.len(),
    ];
    ensure!(
        n > 0 && lens.iter().all(|&l| l == n),
        "writing {}: a {}x{} base with planes of {lens:?} values",
        path.display(),
        base.width,
        base.height
    );
    let layout = Layout {
        version: VERSION,
        width: base.width,
        height: base.height,
        meta: &base.meta,
        scale: Some(base.scale.to_bits()),
    };
    write_planes(path, layout, image_sum, |p, r| {
        let mut out = Vec::with_capacity(r.len() * BASE_PLANES[p].1 * word_bytes(VERSION, p));
        match p {
            0 => base.radiance[r]
                .iter()
                .flatten()
                .for_each(|h| out.extend_from_slice(&h.to_bits().to_le_bytes())),
            1 => base.distance[r]
                .iter()
                .for_each(|d| out.extend_from_slice(&d.to_bits().to_le_bytes())),
            2 => base.object_id[r]
                .iter()
                .for_each(|o| out.extend_from_slice(&o.to_le_bytes())),
            3 => base.primitive_id[r]
                .iter()
                .for_each(|o| out.extend_from_slice(&o.to_le_bytes())),
            _ => base.normal[r]
                .iter()
                .flat_map(|n| n.to_array())
                .for_each(|x| out.extend_from_slice(&x.to_bits().to_le_bytes())),
        }
        out
    })
}

/// What a file's header says beside its planes.
struct Layout<'a> {
    version: u32,
    width: u32,
    height: u32,
    meta: &'a RangeMeta,
    scale: Option<u32>,
}

/// Writes the planes of `layout.version` to `path`, plane `p`'s pixels
/// `r` as `bytes(p, r)` gives them (little-endian words).
fn write_planes(
    path: &Path,
    layout: Layout,
    image_sum: &str,
    bytes: impl Fn(usize, Range<usize>) -> Vec<u8> + Sync,
) -> Result<()> {
    let n = layout.width as usize * layout.height as usize;
    let table = self::layout(layout.version);
    // Every chunk compressed on every core; the header, which comes first,
    // needs their lengths, so the compressed chunks are held until written
    // (a few bytes a pixel: a fraction of the image's own).
    let all: Vec<(usize, Range<usize>)> = (0..table.len())
        .flat_map(|p| chunks(n).map(move |r| (p, r)))
        .collect();
    let stored: Vec<Vec<u8>> = all
        .into_par_iter()
        .map(|(p, r)| {
            let size = word_bytes(layout.version, p);
            zstd::bulk::compress(&regroup(&bytes(p, r), size), LEVEL)
                .with_context(|| format!("writing {}: compressing a chunk", path.display()))
        })
        .collect::<Result<_>>()?;
    let per_plane = n.div_ceil(CHUNK);
    let planes = table
        .iter()
        .zip(stored.chunks(per_plane))
        .map(|(&(name, words_per_pixel), chunks)| PlaneRecord {
            name: name.into(),
            words_per_pixel,
            chunks: chunks.iter().map(|c| hex(fnv1a64(c))).collect(),
            bytes: chunks.iter().map(|c| c.len() as u64).collect(),
        })
        .collect();
    let header = Header {
        version: layout.version,
        width: layout.width,
        height: layout.height,
        camera: CameraBits::of(&layout.meta.camera),
        time: layout.meta.time.to_bits(),
        scene: layout.meta.scene.clone(),
        image_fnv1a64: image_sum.into(),
        chunk_pixels: CHUNK,
        scale: layout.scale,
        planes,
    };
    let json = serde_json::to_vec(&header).context("encoding a planes file's header")?;
    write_atomically(path, |tmp| {
        let file = File::create(tmp).with_context(|| format!("creating {}", tmp.display()))?;
        let mut out = BufWriter::with_capacity(1 << 20, file);
        // Still an I/O error, worded for the person who asked for the file,
        // so that the C API reports it as one (`RW_IO`).
        let fail = |e: std::io::Error| {
            let words = format!(
                "{}: cannot write: {}",
                tmp.display(),
                super::write_error::describe(&e)
            );
            anyhow::Error::new(std::io::Error::new(e.kind(), words))
        };
        out.write_all(MAGIC).map_err(fail)?;
        out.write_all(&(json.len() as u32).to_le_bytes())
            .map_err(fail)?;
        out.write_all(&json).map_err(fail)?;
        out.write_all(hex(fnv1a64(&json)).as_bytes())
            .map_err(fail)?;
        for chunk in &stored {
            out.write_all(chunk).map_err(fail)?;
        }
        out.into_inner()
            .map_err(|e| fail(e.into_error()))?
            .sync_all()
            .map_err(fail)
    })
}

/// An open planes file whose header is read and checked: any chunk of any
/// plane can be read from it alone.
pub struct PlanesFile {
    file: File,
    path: std::path::PathBuf,
    header: Header,
    /// Where each plane's chunks start and end in the file.
    spans: Vec<Vec<Range<u64>>>,
    pixels: usize,
}

impl PlanesFile {
    /// Opens the planes file at `path`, checking its header against its
    /// checksum and against `image_sum` (the checksum of the EXR it must
    /// have been written with), and its length against the header.
    pub fn open(path: &Path, image_sum: &str) -> Result<PlanesFile> {
        let name = path.display();
        let mut file = File::open(path).with_context(|| format!("{name}: cannot open"))?;
        let len = file
            .metadata()
            .with_context(|| format!("{name}: cannot read"))?
            .len();
        let mut start = [0u8; 12];
        file.read_exact(&mut start)
            .map_err(|_| anyhow!("{name}: cut short before its header"))?;
        ensure!(
            &start[..8] == MAGIC,
            "{name}: not a rangewalk planes file (it does not start with `RWPLANES`)"
        );
        let header_len = u32::from_le_bytes(start[8..12].try_into().expect("4 bytes"));
        ensure!(
            header_len <= MAX_HEADER && 12 + u64::from(header_len) + 16 <= len,
            "{name}: header of {header_len} bytes in a file of {len}: the file is damaged"
        );
        let mut json = vec![0u8; header_len as usize];
        let mut sum = [0u8; 16];
        file.read_exact(&mut json)
            .and_then(|_| file.read_exact(&mut sum))
            .with_context(|| format!("{name}: cannot read its header"))?;
        ensure!(
            hex(fnv1a64(&json)).as_bytes() == sum,
            "{name}: its header is damaged (its checksum differs from the one written after it)"
        );
        let header: Header = serde_json::from_slice(&json)
            .with_context(|| format!("{name}: its header is not a planes file's"))?;
        ensure!(
            (1..=VERSION).contains(&header.version),
            "{name}: planes file version {}, this rangewalk reads versions 1 to {VERSION}",
            header.version
        );
        ensure!(
            header.image_fnv1a64 == image_sum,
            "{name}: written with an image of checksum {}, not {image_sum}: it belongs to another image",
            header.image_fnv1a64
        );
        let (w, h) = (header.width, header.height);
        let n = w as usize * h as usize;
        ensure!(
            n > 0 && n as u64 <= MAX_PIXELS,
            "{name}: {w}x{h} pixels, outside 1 to {MAX_PIXELS}"
        );
        ensure!(
            header.chunk_pixels == CHUNK,
            "{name}: chunks of {} pixels, expected {CHUNK}",
            header.chunk_pixels
        );
        let count = n.div_ceil(CHUNK);
        let raw = header.version == 1;
        let table = layout(header.version);
        ensure!(
            header.planes.len() == table.len() && (header.version >= 3) == header.scale.is_some(),
            "{name}: {} planes, expected {} for version {}",
            header.planes.len(),
            table.len(),
            header.version
        );
        for (p, &(plane, words)) in table.iter().enumerate() {
            let r = header.planes.get(p);
            ensure!(
                r.is_some_and(|r| r.name == plane
                    && r.words_per_pixel == words
                    && r.chunks.len() == count
                    && r.bytes.len() == if raw { 0 } else { count }),
                "{name}: plane {p} is not `{plane}` of {words} word(s) a pixel in {count} chunk(s)"
            );
        }
        // Each chunk's place: version 1's chunks are the raw words.
        let mut at = 12 + u64::from(header_len) + 16;
        let spans: Vec<Vec<Range<u64>>> = table
            .iter()
            .enumerate()
            .map(|(p, &(_, words))| {
                chunks(n)
                    .enumerate()
                    .map(|(c, r)| {
                        let size = if raw {
                            (4 * words * r.len()) as u64
                        } else {
                            header.planes[p].bytes[c]
                        };
                        let span = at..at.saturating_add(size);
                        at = span.end;
                        span
                    })
                    .collect()
            })
            .collect();
        ensure!(
            len == at,
            "{name}: {len} bytes, expected {at} for {w}x{h} pixels: the file is cut short or damaged"
        );
        Ok(PlanesFile {
            file,
            path: path.to_path_buf(),
            header,
            spans,
            pixels: n,
        })
    }

    /// The bytes of the file that chunk `c` of plane `p` (in file order)
    /// occupies.
    pub fn chunk_span(&self, p: usize, c: usize) -> Option<Range<u64>> {
        self.spans.get(p)?.get(c).cloned()
    }

    /// Chunk `c` of plane `p`: its pixels' words as little-endian bytes,
    /// read and checked alone.
    pub fn read_chunk(&self, p: usize, c: usize) -> Result<Vec<u8>> {
        let (plane, words) = layout(self.header.version)[p];
        let name = self.path.display();
        let span = self
            .chunk_span(p, c)
            .with_context(|| format!("{name}: no chunk {c} of plane {p}"))?;
        let mut stored = vec![0u8; (span.end - span.start) as usize];
        self.file
            .read_exact_at(&mut stored, span.start)
            .with_context(|| format!("{name}: cannot read chunk {c} of `{plane}`"))?;
        let mut h = Fnv::default();
        h.write(&stored);
        ensure!(
            h.hex() == self.header.planes[p].chunks[c],
            "{name}: chunk {c} of plane `{plane}` (bytes {} to {}) is damaged: its checksum differs from the header's",
            span.start,
            span.end
        );
        if self.header.version == 1 {
            return Ok(stored);
        }
        let pixels = CHUNK.min(self.pixels - c * CHUNK);
        let size = word_bytes(self.header.version, p);
        let want = size * words * pixels;
        // The checksum matched, so the chunk is as written: a failure here
        // is a writer's fault, named all the same.
        let grouped = zstd::bulk::decompress(&stored, want)
            .ok()
            .filter(|g| g.len() == want)
            .with_context(|| {
                format!("{name}: chunk {c} of plane `{plane}` does not decode to {pixels} pixels")
            })?;
        Ok(ungroup(&grouped, size))
    }

    /// The file's version (see [`VERSION`]): 1 and 2 hold a range image
    /// ([`PlanesFile::read`]), 3 a base ([`PlanesFile::read_base`]).
    pub fn version(&self) -> u32 {
        self.header.version
    }

    fn meta(&self) -> Result<RangeMeta> {
        let (w, h) = (self.header.width, self.header.height);
        let camera = self
            .header
            .camera
            .camera(w, h)
            .with_context(|| format!("{}: header", self.path.display()))?;
        Ok(RangeMeta {
            camera,
            time: f32::from_bits(self.header.time),
            scene: self.header.scene.clone(),
        })
    }

    /// What synthesis keeps of the base, from a version-3 file, every
    /// chunk checked as it is read.
    pub fn read_base(self) -> Result<BasePlanes> {
        let (name, version) = (self.path.display(), self.header.version);
        let scale = match self.header.scale {
            Some(s) if version >= 3 => f32::from_bits(s),
            _ => bail!("{name}: planes file version {version} holds a range image, not a base"),
        };
        ensure!(
            scale.is_finite() && scale > 0.0,
            "{name}: radiance scale {scale} is not a positive number"
        );
        let meta = self.meta()?;
        let word = |b: &[u8]| u32::from_le_bytes(b.try_into().expect("4 bytes"));
        let half = |b: &[u8], i: usize| f16::from_bits(u16::from_le_bytes([b[i], b[i + 1]]));
        let radiance = self.read_plane(0, |b| [half(b, 0), half(b, 2), half(b, 4)])?;
        let distance = self.read_plane(1, |b| f32::from_bits(word(b)))?;
        let object_id = self.read_plane(2, word)?;
        let primitive_id = self.read_plane(3, word)?;
        let vec3s = |b: &[u8]| {
            let w = |i: usize| f32::from_le_bytes(b[i..i + 4].try_into().expect("4 bytes"));
            Vec3::new(w(0), w(4), w(8))
        };
        let normal = self.read_plane(4, vec3s)?;
        Ok(BasePlanes {
            width: self.header.width,
            height: self.header.height,
            radiance,
            scale,
            distance,
            object_id,
            primitive_id,
            normal,
            meta,
        })
    }

    /// Reads every chunk of every plane, checking each: whether the file
    /// is whole and undamaged, whatever its version.
    pub fn verify(self) -> Result<()> {
        if self.header.version >= 3 {
            self.read_base().map(drop)
        } else {
            self.read().map(drop)
        }
    }

    /// The whole range image, from a version 1 or 2 file, every chunk
    /// checked as it is read.
    pub fn read(self) -> Result<RangeImage> {
        let (w, h) = (self.header.width, self.header.height);
        let version = self.header.version;
        ensure!(
            version < 3,
            "{}: planes file version {version} holds a base, not a range image: read the image from its EXR",
            self.path.display()
        );
        let meta = self.meta()?;
        let vec3s = |b: &[u8]| {
            let w = |i: usize| f32::from_le_bytes(b[i..i + 4].try_into().expect("4 bytes"));
            Vec3::new(w(0), w(4), w(8))
        };
        let word = |b: &[u8]| u32::from_le_bytes(b.try_into().expect("4 bytes"));
        let radiance = self.read_plane(0, vec3s)?;
        let distance = self.read_plane(1, |b| f32::from_bits(word(b)))?;
        let object_id = self.read_plane(2, word)?;
        let primitive_id = self.read_plane(3, word)?;
        let normal = self.read_plane(4, vec3s)?;
        Ok(RangeImage {
            width: w,
            height: h,
            radiance,
            distance,
            object_id,
            primitive_id,
            normal,
            meta,
        })
    }

    /// Plane `p`: its chunks read and checked on every core, each pixel's
    /// words decoded by `decode`.
    fn read_plane<T: Send + Copy + Default>(
        &self,
        p: usize,
        decode: impl Fn(&[u8]) -> T + Sync,
    ) -> Result<Vec<T>> {
        let (plane, words) = layout(self.header.version)[p];
        let size = word_bytes(self.header.version, p) * words;
        let mut out = Vec::new();
        crate::alloc::reserve(&mut out, self.pixels, || {
            format!("the `{plane}` plane of {}", self.path.display())
        })?;
        out.resize(self.pixels, T::default());
        out.par_chunks_mut(CHUNK)
            .enumerate()
            .try_for_each(|(c, dst)| {
                let bytes = self.read_chunk(p, c)?;
                for (d, b) in dst.iter_mut().zip(bytes.chunks_exact(size)) {
                    *d = decode(b);
                }
                Ok::<_, anyhow::Error>(())
            })?;
        Ok(out)
    }
}

/// Reads the range image of the planes file at `path`, checking its header
/// against `image_sum` (the checksum of the EXR it must have been written
/// with) and every chunk against the header as it is read. Errors name the
/// file, and the plane and chunk at fault.
pub fn read(path: &Path, image_sum: &str) -> Result<RangeImage> {
    PlanesFile::open(path, image_sum)?.read()
}

/// Reads the base of the version-3 planes file at `path`, checked as
/// [`read`] checks a range image.
pub fn read_base(path: &Path, image_sum: &str) -> Result<BasePlanes> {
    PlanesFile::open(path, image_sum)?.read_base()
}

/// Whether the planes file at `path`, of any version, was written with the
/// image of checksum `image_sum` and reads whole, every chunk checked.
pub fn verify(path: &Path, image_sum: &str) -> Result<()> {
    PlanesFile::open(path, image_sum)?.verify()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regrouping_is_undone() {
        let words: Vec<u8> = (0..4 * 37).map(|i| (i * 7 % 251) as u8).collect();
        let g = regroup(&words, 4);
        assert_eq!(g[..4], [words[0], words[4], words[8], words[12]]);
        assert_eq!(ungroup(&g, 4), words);
        let g = regroup(&words, 2);
        assert_eq!(g[..3], [words[0], words[2], words[4]]);
        assert_eq!(ungroup(&g, 2), words);
    }
}
