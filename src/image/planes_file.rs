//! A range image's planes stored raw beside its EXR, so that synthesis
//! opens a base without decoding a compressed file: decoding and hashing
//! a base's EXR (eighteen ZIP-compressed channels, the light layers
//! among them) took most of a second for a 2,544² sphere's window, while
//! reading the planes synthesis needs as they lie on disk takes
//! milliseconds.
//!
//! The file holds the range image's planes (radiance, distance, object and
//! primitive ids, normals; not the light layers, which re-shading does not
//! read) as little-endian 32-bit words, each plane cut into chunks of
//! [`CHUNK`] pixels with an FNV-1a 64 checksum apiece, so that every chunk
//! is checked as it is read, on all cores at once. The header holds the
//! camera (floats as bit patterns, so it reads back bit for bit), the
//! chunks' checksums and the content checksum of the EXR the planes were
//! made with; it is followed by its own checksum. A reader that holds the
//! EXR's checksum (the bake's manifest) therefore trusts every byte it
//! reads: header, then chunks.
//!
//! ```text
//! "RWPLANES"  u32 LE header length L  header (JSON, L bytes)  FNV-1a 64 of the header (16 hex digits)
//! plane 0 (radiance, 3 words a pixel), plane 1 (distance), 2 (object_id), 3 (primitive_id), 4 (normal, 3)
//! ```

use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::os::unix::fs::FileExt;
use std::path::Path;

use anyhow::{anyhow, bail, ensure, Context, Result};
use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{write_atomically, RangeImage, RangeMeta, MAX_PIXELS};
use crate::camera::{Camera, Projection, Window};
use crate::checksum::{fnv1a64, hex, Fnv};

const MAGIC: &[u8; 8] = b"RWPLANES";
/// The layout's version, in the header.
pub const VERSION: u32 = 1;
/// Pixels per chunk: small enough that a window's chunks keep both cores
/// busy, large enough that the header's table of checksums stays short.
pub const CHUNK: usize = 1 << 16;
/// The largest header accepted: a header names its chunks' checksums,
/// some 20 bytes each, so even an 8,192² image needs well under this.
const MAX_HEADER: u32 = 16 << 20;

/// The planes in file order, with their 32-bit words per pixel.
const PLANES: [(&str, usize); 5] = [
    ("radiance", 3),
    ("distance", 1),
    ("object_id", 1),
    ("primitive_id", 1),
    ("normal", 3),
];

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
    /// FNV-1a 64 of each chunk's bytes, 16 hex digits.
    chunks: Vec<String>,
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
fn plane_bytes(image: &RangeImage, p: usize, range: std::ops::Range<usize>) -> Vec<u8> {
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

fn chunks(n: usize) -> impl Iterator<Item = std::ops::Range<usize>> + Clone {
    (0..n.div_ceil(CHUNK)).map(move |c| c * CHUNK..((c + 1) * CHUNK).min(n))
}

/// Writes `image`'s planes to `path` (atomically), naming `image_sum`,
/// the content checksum of the EXR written with them.
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
    // The checksums first, chunk by chunk on every core; the bytes are
    // made again as they are written, so no second copy of the image is
    // ever held.
    let planes = PLANES
        .iter()
        .enumerate()
        .map(|(p, &(name, words_per_pixel))| {
            let ranges: Vec<_> = chunks(n).collect();
            PlaneRecord {
                name: name.into(),
                words_per_pixel,
                chunks: ranges
                    .into_par_iter()
                    .map(|r| hex(fnv1a64(&plane_bytes(image, p, r))))
                    .collect(),
            }
        })
        .collect();
    let header = Header {
        version: VERSION,
        width: image.width,
        height: image.height,
        camera: CameraBits::of(&image.meta.camera),
        time: image.meta.time.to_bits(),
        scene: image.meta.scene.clone(),
        image_fnv1a64: image_sum.into(),
        chunk_pixels: CHUNK,
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
        for p in 0..PLANES.len() {
            for r in chunks(n) {
                out.write_all(&plane_bytes(image, p, r)).map_err(fail)?;
            }
        }
        out.into_inner()
            .map_err(|e| fail(e.into_error()))?
            .sync_all()
            .map_err(fail)
    })
}

/// Reads the range image of the planes file at `path`, checking its header
/// against `image_sum` (the checksum of the EXR it must have been written
/// with) and every chunk against the header as it is read. Errors name the
/// file, and the plane and chunk at fault.
pub fn read(path: &Path, image_sum: &str) -> Result<RangeImage> {
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
        header.version == VERSION,
        "{name}: planes file version {}, this rangewalk reads version {VERSION}",
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
    for (p, &(plane, words)) in PLANES.iter().enumerate() {
        let r = header.planes.get(p);
        ensure!(
            r.is_some_and(|r| r.name == plane
                && r.words_per_pixel == words
                && r.chunks.len() == count),
            "{name}: plane {p} is not `{plane}` of {words} word(s) a pixel in {count} chunk(s)"
        );
    }
    let data = 12 + u64::from(header_len) + 16;
    let words: usize = PLANES.iter().map(|p| p.1).sum();
    let want = data + 4 * (words * n) as u64;
    ensure!(
        len == want,
        "{name}: {len} bytes, expected {want} for {w}x{h} pixels: the file is cut short or damaged"
    );
    let camera = header
        .camera
        .camera(w, h)
        .with_context(|| format!("{name}: header"))?;

    let mut offset = data;
    let mut next = |p: usize| {
        let at = offset;
        offset += 4 * (PLANES[p].1 * n) as u64;
        at
    };
    let f = &file;
    let sums = |p: usize| header.planes[p].chunks.as_slice();
    let vec3s = |b: &[u8]| {
        let w = |i: usize| f32::from_le_bytes(b[i..i + 4].try_into().expect("4 bytes"));
        Vec3::new(w(0), w(4), w(8))
    };
    let word = |b: &[u8]| u32::from_le_bytes(b.try_into().expect("4 bytes"));
    let radiance = read_plane(f, path, 0, next(0), sums(0), n, vec3s)?;
    let distance = read_plane(f, path, 1, next(1), sums(1), n, |b| f32::from_bits(word(b)))?;
    let object_id = read_plane(f, path, 2, next(2), sums(2), n, word)?;
    let primitive_id = read_plane(f, path, 3, next(3), sums(3), n, word)?;
    let normal = read_plane(f, path, 4, next(4), sums(4), n, vec3s)?;
    Ok(RangeImage {
        width: w,
        height: h,
        radiance,
        distance,
        object_id,
        primitive_id,
        normal,
        meta: RangeMeta {
            camera,
            time: f32::from_bits(header.time),
            scene: header.scene,
        },
    })
}

/// Plane `p` of `n` pixels at byte `offset`: its chunks read and checked
/// on every core, each pixel's words decoded by `decode`.
fn read_plane<T: Send + Copy + Default>(
    file: &File,
    path: &Path,
    p: usize,
    offset: u64,
    sums: &[String],
    n: usize,
    decode: impl Fn(&[u8]) -> T + Sync,
) -> Result<Vec<T>> {
    let (plane, words) = PLANES[p];
    let size = 4 * words;
    let mut out = Vec::new();
    crate::alloc::reserve(&mut out, n, || {
        format!("the `{plane}` plane of {}", path.display())
    })?;
    out.resize(n, T::default());
    out.par_chunks_mut(CHUNK)
        .zip(sums)
        .enumerate()
        .try_for_each(|(c, (dst, sum))| {
            let at = offset + (c * CHUNK * size) as u64;
            let mut bytes = vec![0u8; dst.len() * size];
            file.read_exact_at(&mut bytes, at).with_context(|| {
                format!("{}: cannot read chunk {c} of `{plane}`", path.display())
            })?;
            let mut h = Fnv::default();
            h.write(&bytes);
            ensure!(
                h.hex() == *sum,
                "{}: chunk {c} of plane `{plane}` (bytes {at} to {}) is damaged: its checksum differs from the header's",
                path.display(),
                at + bytes.len() as u64
            );
            for (d, b) in dst.iter_mut().zip(bytes.chunks_exact(size)) {
                *d = decode(b);
            }
            Ok(())
        })?;
    Ok(out)
}
