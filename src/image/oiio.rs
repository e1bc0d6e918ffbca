//! OpenImageIO through the coarse C++ shim in `ffi/oiio.cc`: whole-file reads
//! and writes of [`Planes`], so the shim never mirrors OIIO's classes.
//!
//! Writes go through the shim's own file proxy, which keeps the OS error of
//! a failed write: OpenImageIO alone says only "File output failed", for a
//! full disk as for anything else, and the message must say which.

use std::path::Path;

use anyhow::{anyhow, Result};
use rayon::prelude::*;

use super::planes::{Attr, DataWindow, Plane, Planes};
use super::{Texture, MAX_PIXELS};

#[cxx::bridge(namespace = "rangewalk::oiio")]
mod ffi {
    /// How a channel's 32-bit words are to be read.
    enum Sample {
        /// IEEE 754 single floats, as bit patterns.
        F32,
        U32,
    }

    struct Channel {
        name: String,
        sample: Sample,
        data: Vec<u32>,
    }

    /// A header attribute: a string when `floats` is empty, otherwise one
    /// float, a 3-vector or a float array.
    struct Attribute {
        name: String,
        floats: Vec<f32>,
        text: String,
    }

    /// A file read: its channels' `data` are empty, their words are in
    /// `words`, in `channels`' order.
    struct Decoded {
        raster: Raster,
        words: UniquePtr<Words>,
    }

    struct Raster {
        width: u32,
        height: u32,
        /// The pixels' (data window's) corner relative to the display
        /// window's, and the display window's size: `(0, 0)` and the
        /// pixels' own size where the two are one.
        x: i64,
        y: i64,
        full_width: u64,
        full_height: u64,
        channels: Vec<Channel>,
        attributes: Vec<Attribute>,
        /// Whether the file stores integers (read back normalized to
        /// `[0, 1]`), which are sRGB-encoded unless the file says otherwise.
        integer_samples: bool,
    }

    // SAFETY: the shim takes shared structs and slices by reference only for
    // the duration of a call, keeps no pointer to them, and returns owned
    // values; its failures are C++ exceptions that cxx turns into `Err`.
    unsafe extern "C++" {
        include!("rangewalk/ffi/oiio.h");

        fn write_image(path: &str, format: &str, image: &Raster) -> Result<()>;
        fn write_rgb8(path: &str, width: u32, height: u32, rgb: &[u8]) -> Result<()>;
        fn read_image(path: &str, max_pixels: u64) -> Result<Decoded>;

        /// One vector of words per channel of a file read.
        type Words;
        /// Channel `c`'s words.
        fn channel(self: &Words, c: usize) -> Result<&[u32]>;
        /// Frees channel `c`'s words.
        fn release(self: Pin<&mut Words>, c: usize);
    }
}

fn path_str(path: &Path) -> Result<&str> {
    path.to_str()
        .ok_or_else(|| anyhow!("{}: path is not valid UTF-8", path.display()))
}

/// The file formats written through OpenImageIO besides PNG.
#[derive(Clone, Copy, Debug)]
pub enum Format {
    Exr,
    Hdr,
}

/// Writes `planes` to `path` in `format`, whatever the file's extension.
/// Takes them by value: their samples become the shim's words in place,
/// so no second copy of the image is made.
pub fn write(path: &Path, format: Format, planes: Planes) -> Result<()> {
    let d = planes.window.unwrap_or(DataWindow {
        x: 0,
        y: 0,
        full_width: planes.width.into(),
        full_height: planes.height.into(),
    });
    let raster = ffi::Raster {
        width: planes.width,
        height: planes.height,
        x: d.x,
        y: d.y,
        full_width: d.full_width,
        full_height: d.full_height,
        channels: planes
            .channels
            .into_iter()
            .map(|(name, plane)| match plane {
                // Collected into the plane's own allocation (floats and
                // words are of one size).
                Plane::F32(v) => ffi::Channel {
                    name,
                    sample: ffi::Sample::F32,
                    data: v.into_iter().map(f32::to_bits).collect(),
                },
                Plane::U32(data) => ffi::Channel {
                    name,
                    sample: ffi::Sample::U32,
                    data,
                },
            })
            .collect(),
        integer_samples: false,
        attributes: planes
            .attributes
            .into_iter()
            .map(|(name, attr)| {
                let (floats, text) = match attr {
                    Attr::Float(x) => (vec![x], String::new()),
                    Attr::Vector(v) => (v.to_vec(), String::new()),
                    Attr::Text(s) => (Vec::new(), s),
                };
                ffi::Attribute { name, floats, text }
            })
            .collect(),
    };
    let format = match format {
        Format::Exr => "openexr",
        Format::Hdr => "hdr",
    };
    Ok(ffi::write_image(path_str(path)?, format, &raster)?)
}

/// Writes 8-bit RGB pixels, row-major and top row first, as PNG.
pub fn write_rgb8(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<()> {
    Ok(ffi::write_rgb8(path_str(path)?, width, height, rgb)?)
}

/// Reads the first subimage of any file OpenImageIO understands.
pub fn read(path: &Path) -> Result<Planes> {
    planes(ffi::read_image(path_str(path)?, MAX_PIXELS)?)
}

/// Reads any image OpenImageIO understands as a linear-RGB texture. Integer
/// samples are decoded from sRGB unless the file declares them linear.
pub fn read_texture(path: &Path) -> Result<Texture> {
    let decoded = ffi::read_image(path_str(path)?, MAX_PIXELS)?;
    let linear = decoded
        .raster
        .attributes
        .iter()
        .any(|a| a.name == "oiio:ColorSpace" && a.text.eq_ignore_ascii_case("linear"));
    let srgb = decoded.raster.integer_samples && !linear;
    planes(decoded)?.into_texture(path, srgb)
}

fn planes(decoded: ffi::Decoded) -> Result<Planes> {
    let ffi::Decoded { raster, mut words } = decoded;
    let Some(mut words) = words.as_mut() else {
        anyhow::bail!("the image reader returned no pixels");
    };
    let n = raster.width as usize * raster.height as usize;
    let mut channels = Vec::with_capacity(raster.channels.len());
    for (c, channel) in raster.channels.into_iter().enumerate() {
        let data = words.channel(c)?;
        anyhow::ensure!(
            data.len() == n,
            "the image reader returned {} words for channel {} of {n} pixels",
            data.len(),
            channel.name
        );
        let plane = if channel.sample == ffi::Sample::U32 {
            Plane::U32(data.to_vec())
        } else {
            Plane::F32(data.par_iter().map(|&w| f32::from_bits(w)).collect())
        };
        // Each channel is let go as soon as it is copied, so that a read
        // never holds a whole image twice.
        words.as_mut().release(c);
        channels.push((channel.name, plane));
    }
    let attributes = raster
        .attributes
        .into_iter()
        .filter_map(|a| {
            let attr = match a.floats.len() {
                0 => Attr::Text(a.text),
                1 => Attr::Float(a.floats[0]),
                3 => Attr::Vector([a.floats[0], a.floats[1], a.floats[2]]),
                _ => return None,
            };
            Some((a.name, attr))
        })
        .collect();
    let whole = (raster.x, raster.y, raster.full_width, raster.full_height)
        == (0, 0, raster.width.into(), raster.height.into());
    Ok(Planes {
        width: raster.width,
        height: raster.height,
        window: (!whole).then_some(DataWindow {
            x: raster.x,
            y: raster.y,
            full_width: raster.full_width,
            full_height: raster.full_height,
        }),
        channels,
        attributes,
    })
}
