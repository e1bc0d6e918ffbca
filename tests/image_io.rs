//! Range-image, HDR, PNG and texture files: round trips through each back
//! end, files of one back end read by the other, and failures that name the
//! file and leave nothing half-written behind.

use std::path::{Path, PathBuf};

use glam::Vec3;
use rangewalk::camera::{Camera, Projection};
use rangewalk::image::{
    exr_io, png_io, read_exr, read_texture, rgbe, write_exr, write_hdr, write_png_preview,
    RangeImage, RangeMeta, NO_HIT,
};

const PROJECTIONS: [Projection; 3] = [
    Projection::Perspective { vfov_deg: 39.3077 },
    Projection::Fisheye,
    Projection::Sphere,
];

/// A 7x5 range image whose every channel varies per pixel, with extreme
/// floats, ids that f32 cannot hold exactly and pixels that hit nothing.
fn sample_image(projection: Projection) -> RangeImage {
    sample_image_of(projection, 7, 5)
}

fn sample_image_of(projection: Projection, width: u32, height: u32) -> RangeImage {
    let camera = Camera::look_at(
        Vec3::new(1.25, -3.5, 0.1),
        Vec3::new(0.3, 0.7, -2.0),
        Vec3::new(0.1, 1.0, 0.05),
        projection,
        width,
        height,
    )
    .unwrap();
    let meta = RangeMeta {
        camera,
        time: 1.0 / 3.0,
        scene: "scènes/cornell.toml spp=64 seed=7".to_string(),
    };
    let mut image = RangeImage::empty(meta);
    for i in 0..image.len() {
        let f = i as f32;
        if i % 4 == 3 {
            continue; // nothing hit: the empty image's values
        }
        image.radiance[i] = Vec3::new((f * 0.37).sin().abs() * 3.0, 1e-30 * f, 3.0e38 / (f + 1.0));
        image.distance[i] = 0.1 + f * 1.618_034;
        image.object_id[i] = [0, 1, 16_777_217, u32::MAX - 1][i % 4];
        image.primitive_id[i] = (i as u32).wrapping_mul(2_654_435_761);
        image.normal[i] = Vec3::new(f.cos(), f.sin(), 0.5).normalize();
    }
    assert!(image.object_id.contains(&NO_HIT));
    image
}

fn assert_message_names(err: anyhow::Error, path: &Path) {
    let message = format!("{err:#}");
    let name = path.file_name().unwrap().to_str().unwrap();
    assert!(message.contains(name), "`{message}` does not name {name}");
}

fn files_in(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    v.sort();
    v
}

#[test]
fn exr_crate_round_trip_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    for projection in PROJECTIONS {
        let image = sample_image(projection);
        let path = dir.path().join(format!("{}.exr", projection.name()));
        exr_io::write(&path, &image).unwrap();
        assert_eq!(exr_io::read(&path).unwrap(), image);
    }
    // Nothing but the finished files is left in the directory.
    assert_eq!(files_in(dir.path()).len(), PROJECTIONS.len());
}

#[test]
fn default_back_end_round_trip_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    for projection in PROJECTIONS {
        let image = sample_image(projection);
        let path = dir.path().join(format!("{}.exr", projection.name()));
        write_exr(&path, &image).unwrap();
        let back = read_exr(&path).unwrap();
        assert_eq!(back.meta.camera, image.meta.camera);
        assert_eq!(back, image);
    }
    assert_eq!(files_in(dir.path()).len(), PROJECTIONS.len());
}

/// The default back end reads files in strips of rows: an image taller
/// than several strips, its last one partial, comes back exact, and the
/// other back end reads the same values from the file.
#[test]
fn tall_images_round_trip_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let image = sample_image_of(Projection::Sphere, 6, 157);
    let path = dir.path().join("tall.exr");
    write_exr(&path, &image).unwrap();
    assert_eq!(read_exr(&path).unwrap(), image);
    assert_eq!(exr_io::read(&path).unwrap(), image);
}

/// A file of `sample_image(Sphere)` written once by OpenImageIO and stored:
/// every build's readers (the pure-Rust one included) must give back
/// exactly the stored values, so the pure-Rust round trips above are tied
/// to a file no pure-Rust code wrote.
#[test]
fn stored_file_reads_back_the_expected_values() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/image_io/sample-sphere.exr");
    let expected = sample_image(Projection::Sphere);
    assert_eq!(exr_io::read(&path).unwrap(), expected);
    assert_eq!(read_exr(&path).unwrap(), expected);
}

#[cfg(feature = "oiio")]
#[test]
fn openimageio_and_exr_crate_read_each_others_files() {
    let dir = tempfile::tempdir().unwrap();
    for projection in PROJECTIONS {
        let image = sample_image(projection);
        let by_oiio = dir.path().join(format!("oiio-{}.exr", projection.name()));
        let by_crate = dir.path().join(format!("crate-{}.exr", projection.name()));
        write_exr(&by_oiio, &image).unwrap();
        exr_io::write(&by_crate, &image).unwrap();
        assert_eq!(exr_io::read(&by_oiio).unwrap(), image, "{by_oiio:?}");
        assert_eq!(read_exr(&by_crate).unwrap(), image, "{by_crate:?}");
    }
}

#[test]
fn missing_truncated_and_foreign_files_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.exr");
    assert_message_names(read_exr(&missing).unwrap_err(), &missing);
    assert_message_names(exr_io::read(&missing).unwrap_err(), &missing);
    for name in ["missing.png", "missing.hdr", "missing.exr"] {
        let p = dir.path().join(name);
        assert_message_names(read_texture(&p).unwrap_err(), &p);
    }
    assert_message_names(
        png_io::read(dir.path().join("m.png")).unwrap_err(),
        Path::new("m.png"),
    );
    assert_message_names(
        rgbe::read(dir.path().join("m.hdr")).unwrap_err(),
        Path::new("m.hdr"),
    );

    let text = dir.path().join("notes.exr");
    std::fs::write(&text, "range images are not made of words\n").unwrap();
    assert_message_names(read_exr(&text).unwrap_err(), &text);
    assert_message_names(exr_io::read(&text).unwrap_err(), &text);

    let full = dir.path().join("full.exr");
    exr_io::write(&full, &sample_image(PROJECTIONS[0])).unwrap();
    let bytes = std::fs::read(&full).unwrap();
    let cut = dir.path().join("cut.exr");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    assert_message_names(read_exr(&cut).unwrap_err(), &cut);
    assert_message_names(exr_io::read(&cut).unwrap_err(), &cut);

    let radiance = vec![Vec3::new(0.5, 1.0, 2.0); 64 * 4];
    let hdr = dir.path().join("cut.hdr");
    rgbe::write(&hdr, 64, 4, &radiance).unwrap();
    let bytes = std::fs::read(&hdr).unwrap();
    std::fs::write(&hdr, &bytes[..bytes.len() - 10]).unwrap();
    assert_message_names(rgbe::read(&hdr).unwrap_err(), &hdr);
    assert_message_names(read_texture(&hdr).unwrap_err(), &hdr);

    let png = dir.path().join("cut.png");
    png_io::write(&png, 64, 4, &vec![77; 64 * 4 * 3]).unwrap();
    let bytes = std::fs::read(&png).unwrap();
    std::fs::write(&png, &bytes[..bytes.len() / 2]).unwrap();
    assert_message_names(png_io::read(&png).unwrap_err(), &png);
    assert_message_names(read_texture(&png).unwrap_err(), &png);
}

#[test]
fn an_exr_without_range_metadata_is_rejected_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plain.exr");
    exr::prelude::write_rgb_file(&path, 4, 3, |x, y| (x as f32, y as f32, 0.5)).unwrap();
    for err in [
        read_exr(&path).unwrap_err(),
        exr_io::read(&path).unwrap_err(),
    ] {
        let message = format!("{err:#}");
        assert!(message.contains("plain.exr"), "{message}");
        assert!(message.contains("rangewalk:cameraPosition"), "{message}");
    }
    // It is, however, a fine texture.
    let texture = read_texture(&path).unwrap();
    assert_eq!((texture.width, texture.height), (4, 3));
    assert_eq!(texture.texels[4 + 2], Vec3::new(2.0, 1.0, 0.5));
}

#[test]
fn failed_writes_leave_no_file_behind() {
    let dir = tempfile::tempdir().unwrap();
    let image = sample_image(PROJECTIONS[0]);

    // A directory that does not exist.
    let nowhere = dir.path().join("no-such-dir").join("view.exr");
    assert_message_names(write_exr(&nowhere, &image).unwrap_err(), &nowhere);
    assert_message_names(exr_io::write(&nowhere, &image).unwrap_err(), &nowhere);
    assert!(!nowhere.exists());

    // An image whose vectors disagree with its size.
    let mut broken = image.clone();
    broken.distance.pop();
    let target = dir.path().join("broken.exr");
    for err in [
        write_exr(&target, &broken).unwrap_err(),
        exr_io::write(&target, &broken).unwrap_err(),
    ] {
        assert_message_names(err, &target);
    }
    let short = dir.path().join("short.hdr");
    assert_message_names(
        write_hdr(&short, 4, 4, &[Vec3::ONE; 15]).unwrap_err(),
        &short,
    );
    let short_png = dir.path().join("short.png");
    assert_message_names(
        write_png_preview(&short_png, 4, 4, &[Vec3::ONE; 15], 0.0).unwrap_err(),
        &short_png,
    );

    // The target is a directory: the file is written, the rename fails, and
    // the temporary file is removed again.
    let occupied = dir.path().join("occupied.exr");
    std::fs::create_dir(&occupied).unwrap();
    std::fs::write(occupied.join("keep"), "x").unwrap();
    assert_message_names(write_exr(&occupied, &image).unwrap_err(), &occupied);
    assert_message_names(exr_io::write(&occupied, &image).unwrap_err(), &occupied);
    let hdr_dir = dir.path().join("occupied.hdr");
    std::fs::create_dir(&hdr_dir).unwrap();
    std::fs::write(hdr_dir.join("keep"), "x").unwrap();
    assert!(write_hdr(&hdr_dir, 1, 1, &[Vec3::ONE]).is_err());
    assert!(rgbe::write(&hdr_dir, 1, 1, &[Vec3::ONE]).is_err());

    assert_eq!(files_in(dir.path()), vec![occupied, hdr_dir]);

    // A failed rewrite keeps the previous finished file intact.
    let kept = dir.path().join("kept.exr");
    write_exr(&kept, &image).unwrap();
    let before = std::fs::read(&kept).unwrap();
    assert!(write_exr(&kept, &broken).is_err());
    assert!(exr_io::write(&kept, &broken).is_err());
    assert_eq!(std::fs::read(&kept).unwrap(), before);
}

#[test]
fn the_format_does_not_follow_the_extension() {
    let dir = tempfile::tempdir().unwrap();
    let image = sample_image(PROJECTIONS[1]);
    let path = dir.path().join("view.png");
    write_exr(&path, &image).unwrap();
    assert_eq!(exr_io::read(&path).unwrap(), image);
    let radiance = hdr_radiance(9, 2);
    let hdr = dir.path().join("sky.exr");
    write_hdr(&hdr, 9, 2, &radiance).unwrap();
    assert!(rgbe_error(&rgbe::read(&hdr).unwrap().texels, &radiance) <= 1.0 / 128.0);
    let preview = dir.path().join("preview.hdr");
    write_png_preview(&preview, 9, 2, &radiance, 0.0).unwrap();
    assert_eq!(png_bytes(&preview).2.len(), 9 * 2 * 3);
    assert_eq!(files_in(dir.path()).len(), 3);
}

/// Raw 8-bit RGB samples of a PNG, as the file stores them.
fn png_bytes(path: &Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

#[test]
fn png_preview_holds_the_tone_mapped_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("preview.png");
    // 255 * sRGB(x): 0.18 -> 117.6, 0.09 -> 84.6, 0.045 -> 59.9, 0.5 -> 187.5,
    // 0.1 -> 89.0, 0.2 -> 123.6; the linear segment gives 0.0031308 -> 10.3.
    let radiance = [
        Vec3::new(0.18, 1.0, 0.0),
        Vec3::new(5.0, -1.0, 0.003_130_8),
        Vec3::new(0.09, 0.045, 0.5),
        Vec3::splat(0.1),
    ];
    write_png_preview(&path, 2, 2, &radiance, 0.0).unwrap();
    let (w, h, bytes) = png_bytes(&path);
    assert_eq!((w, h), (2, 2));
    assert_eq!(bytes, [118, 255, 0, 255, 0, 10, 85, 60, 188, 89, 89, 89]);
    // One stop of exposure doubles the light before encoding.
    write_png_preview(&path, 2, 2, &radiance, 1.0).unwrap();
    let (_, _, brighter) = png_bytes(&path);
    assert_eq!(&brighter[6..], &[118, 85, 255, 124, 124, 124]);

    // Read back as a texture: linear values that encode to within half an
    // 8-bit step of the originals.
    let srgb = |x: f32| 1.055 * x.powf(1.0 / 2.4) - 0.055;
    let texture = read_texture(&path).unwrap();
    for (got, want) in texture.texels[2]
        .to_array()
        .iter()
        .zip([0.18f32, 0.09, 1.0])
    {
        let off = (srgb(*got) - srgb(want)).abs() * 255.0;
        assert!(off <= 0.5 + 1e-3, "{got} vs {want}: {off} steps");
    }
    let png_texture = png_io::read(&path).unwrap();
    assert_eq!(png_texture.texels.len(), 4);
    for (a, b) in png_texture.texels.iter().zip(&texture.texels) {
        assert!((*a - *b).abs().max_element() < 1e-6, "{a} vs {b}");
    }
}

#[test]
fn grey_sixteen_bit_png_is_an_srgb_texture() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("grey16.png");
    let levels = [0u16, 32768, 65535];
    {
        let file = std::fs::File::create(&path).unwrap();
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), 3, 1);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Sixteen);
        let mut w = enc.write_header().unwrap();
        let data: Vec<u8> = levels.iter().flat_map(|v| v.to_be_bytes()).collect();
        w.write_image_data(&data).unwrap();
    }
    for texture in [png_io::read(&path).unwrap(), read_texture(&path).unwrap()] {
        // sRGB 0.5 decodes to 0.2140.
        let want = [0.0, 0.214_041, 1.0];
        for (t, w) in texture.texels.iter().zip(want) {
            assert!(
                (*t - Vec3::splat(w)).abs().max_element() < 1e-4,
                "{t} vs {w}"
            );
        }
    }
}

/// Largest relative error of RGBE against the original, relative to each
/// pixel's brightest channel, as the shared exponent quantizes.
fn rgbe_error(got: &[Vec3], want: &[Vec3]) -> f32 {
    got.iter()
        .zip(want)
        .map(|(g, w)| (*g - *w).abs().max_element() / w.max_element().max(1e-30))
        .fold(0.0, f32::max)
}

fn hdr_radiance(width: u32, height: u32) -> Vec<Vec3> {
    (0..width * height)
        .map(|i| {
            let f = i as f32;
            // Runs of equal pixels on the left half, varying ones on the right.
            if i % width < width / 2 {
                Vec3::new(0.25, 0.5, 1.0)
            } else {
                Vec3::new(
                    1e-3 * f,
                    (f * 0.3).sin().abs() * 40.0 + 0.01,
                    1e5 / (f + 1.0),
                )
            }
        })
        .collect()
}

#[test]
fn hdr_round_trips_within_rgbe_quantization() {
    let dir = tempfile::tempdir().unwrap();
    for (width, height) in [(40, 3), (5, 2)] {
        let radiance = hdr_radiance(width, height);
        let path = dir.path().join(format!("{width}.hdr"));
        write_hdr(&path, width, height, &radiance).unwrap();
        let pure = dir.path().join(format!("{width}-pure.hdr"));
        rgbe::write(&pure, width, height, &radiance).unwrap();
        for file in [&path, &pure] {
            for texture in [rgbe::read(file).unwrap(), read_texture(file).unwrap()] {
                assert_eq!((texture.width, texture.height), (width, height));
                // One mantissa step of 1/128 at worst, relative to the
                // pixel's largest channel.
                let err = rgbe_error(&texture.texels, &radiance);
                assert!(err <= 1.0 / 128.0, "{file:?}: relative error {err}");
            }
        }
    }
}

#[cfg(feature = "oiio")]
#[test]
fn openimageio_and_pure_rgbe_agree_on_each_others_files() {
    let dir = tempfile::tempdir().unwrap();
    let radiance = hdr_radiance(40, 3);
    let by_oiio = dir.path().join("oiio.hdr");
    let by_rust = dir.path().join("rust.hdr");
    write_hdr(&by_oiio, 40, 3, &radiance).unwrap();
    rgbe::write(&by_rust, 40, 3, &radiance).unwrap();
    for file in [&by_oiio, &by_rust] {
        let ours = rgbe::read(file).unwrap();
        let theirs = read_texture(file).unwrap();
        // Both decode the same bytes; they may differ only by the half step
        // Radiance adds when decoding.
        assert!(
            rgbe_error(&theirs.texels, &ours.texels) <= 1.0 / 256.0,
            "{file:?}"
        );
    }
    // Both encoders truncate mantissas the same way.
    let a = rgbe::read(&by_oiio).unwrap().texels;
    let b = rgbe::read(&by_rust).unwrap().texels;
    assert_eq!(a, b);
}

/// A texture whose header declares more pixels than an image may hold
/// here is refused by name, whichever back end reads it, before anything
/// is allocated for it (a fuzzed file of a few bytes once took 24 GB).
#[test]
fn textures_declaring_huge_sizes_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.hdr");
    let mut file = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 10000 +X 10000\n".to_vec();
    file.extend([1, 1, 1, 128]);
    std::fs::write(&path, file).unwrap();
    let err = read_texture(&path).unwrap_err();
    let message = format!("{err:#}");
    assert_message_names(err, &path);
    assert!(message.contains("than the 67108864"), "{message}");
}

/// The sample image of `projection` as a 7x5 window at (9, 4) of a 20x12
/// projection, and the window's camera.
fn windowed_sample_image(projection: Projection) -> (RangeImage, Camera) {
    let image = sample_image_of(projection, 20, 12);
    let cropped = image.meta.camera.cropped(9, 4, 7, 5).unwrap();
    let image = RangeImage {
        meta: RangeMeta {
            camera: cropped,
            ..image.meta
        },
        ..sample_image(projection)
    };
    (image, cropped)
}

#[test]
fn a_window_of_a_projection_round_trips_through_both_back_ends() {
    let dir = tempfile::tempdir().unwrap();
    for projection in PROJECTIONS {
        let (image, cropped) = windowed_sample_image(projection);
        let (a, b) = (dir.path().join("a.exr"), dir.path().join("b.exr"));
        write_exr(&a, &image).unwrap();
        exr_io::write(&b, &image).unwrap();
        for (path, read) in [
            (&a, exr_io::read(&a).unwrap()),
            (&b, read_exr(&b).unwrap()),
            (&a, read_exr(&a).unwrap()),
        ] {
            assert_eq!(read, image, "{projection:?}: {}", path.display());
        }
        assert_eq!(
            rangewalk::image::exr_content_hash(&a).unwrap(),
            rangewalk::image::exr_content_hash(&b).unwrap()
        );
        // The window is part of what the checksum covers.
        write_exr(&b, &sample_image(projection)).unwrap();
        assert_ne!(
            rangewalk::image::exr_content_hash(&a).unwrap(),
            rangewalk::image::exr_content_hash(&b).unwrap()
        );
        // Its pixels look where the whole projection's do.
        let whole = sample_image_of(projection, 20, 12).meta.camera;
        let (r, w) = (cropped.ray(1.5, 2.5), whole.ray(10.5, 6.5));
        assert_eq!(r.map(|r| r.dir), w.map(|r| r.dir));
        if let Some(r) = r {
            let p = r.at(3.0);
            let (pc, pw) = (cropped.project(p).unwrap(), whole.project(p).unwrap());
            assert!((pc + glam::Vec2::new(9.0, 4.0) - pw).length() < 1e-3);
        }
    }
}

#[test]
fn a_planes_file_round_trips_bit_for_bit_and_names_the_damaged_chunk() {
    use rangewalk::image::planes_file::{self, CHUNK};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.planes");
    for projection in PROJECTIONS {
        // A window of a projection: the camera must come back with it.
        let (image, _) = windowed_sample_image(projection);
        planes_file::write(&path, &image, "0123456789abcdef").unwrap();
        assert_eq!(
            planes_file::read(&path, "0123456789abcdef").unwrap(),
            image,
            "{projection:?}"
        );
        let e = format!(
            "{:#}",
            planes_file::read(&path, "fedcba9876543210").unwrap_err()
        );
        assert!(e.contains("a.planes") && e.contains("another image"), "{e}");
    }
    // Three chunks a plane; one bit of the second chunk of `distance`
    // flipped is found, and named, while every other chunk still reads
    // alone, as it was written.
    let (w, h) = (300, 500);
    assert_eq!((w * h as usize).div_ceil(CHUNK), 3);
    let image = sample_image_of(Projection::Sphere, w as u32, h);
    planes_file::write(&path, &image, "0123456789abcdef").unwrap();
    assert_eq!(planes_file::read(&path, "0123456789abcdef").unwrap(), image);
    let n = w * h as usize;
    let words = |p: usize, c: usize| -> Vec<u8> {
        let r = c * CHUNK..((c + 1) * CHUNK).min(n);
        match p {
            1 => image.distance[r]
                .iter()
                .flat_map(|d| d.to_le_bytes())
                .collect(),
            4 => image.normal[r]
                .iter()
                .flat_map(|v| v.to_array())
                .flat_map(|x| x.to_le_bytes())
                .collect(),
            _ => unreachable!(),
        }
    };
    let file = planes_file::PlanesFile::open(&path, "0123456789abcdef").unwrap();
    let span = file.chunk_span(1, 1).unwrap();
    // Compressed: the sample's smooth planes take less than their words.
    let len = std::fs::metadata(&path).unwrap().len();
    assert!(len < 4 * 9 * n as u64, "{len} bytes");
    drop(file);
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[(span.start + span.end) as usize / 2] ^= 0x10;
    std::fs::write(&path, &bytes).unwrap();
    let e = format!(
        "{:#}",
        planes_file::read(&path, "0123456789abcdef").unwrap_err()
    );
    assert!(
        e.contains("a.planes")
            && e.contains("chunk 1 of plane `distance`")
            && e.contains(&format!("bytes {} to {}", span.start, span.end))
            && e.contains("damaged"),
        "{e}"
    );
    let file = planes_file::PlanesFile::open(&path, "0123456789abcdef").unwrap();
    assert!(file.read_chunk(1, 1).is_err());
    for (p, c) in [(1, 0), (1, 2), (4, 1)] {
        assert!(file.read_chunk(p, c).unwrap() == words(p, c), "{p} {c}");
    }
    drop(file);
    // Cut short, and not a planes file at all.
    std::fs::write(&path, &bytes[..bytes.len() - 4]).unwrap();
    let e = format!(
        "{:#}",
        planes_file::read(&path, "0123456789abcdef").unwrap_err()
    );
    assert!(e.contains("a.planes") && e.contains("cut short"), "{e}");
    std::fs::write(&path, b"P6 not at all").unwrap();
    let e = format!(
        "{:#}",
        planes_file::read(&path, "0123456789abcdef").unwrap_err()
    );
    assert!(e.contains("not a rangewalk planes file"), "{e}");
    let e = format!(
        "{:#}",
        planes_file::read(&dir.path().join("none.planes"), "0123456789abcdef").unwrap_err()
    );
    assert!(e.contains("none.planes"), "{e}");
}

/// A planes file as version 1 wrote it (bakes of manifest version 6): the
/// words raw, no chunk lengths.
fn version_1_planes(image: &RangeImage, sum: &str) -> Vec<u8> {
    use rangewalk::checksum::{fnv1a64, hex};
    use rangewalk::image::planes_file::CHUNK;
    let n = image.len();
    let v3 = |v: &[Vec3]| -> Vec<u8> {
        v.iter()
            .flat_map(|v| v.to_array())
            .flat_map(|x| x.to_le_bytes())
            .collect()
    };
    let planes: Vec<(&str, usize, Vec<u8>)> = vec![
        ("radiance", 3, v3(&image.radiance)),
        (
            "distance",
            1,
            image
                .distance
                .iter()
                .flat_map(|d| d.to_le_bytes())
                .collect(),
        ),
        (
            "object_id",
            1,
            image
                .object_id
                .iter()
                .flat_map(|d| d.to_le_bytes())
                .collect(),
        ),
        (
            "primitive_id",
            1,
            image
                .primitive_id
                .iter()
                .flat_map(|d| d.to_le_bytes())
                .collect(),
        ),
        ("normal", 3, v3(&image.normal)),
    ];
    let records: Vec<_> = planes
        .iter()
        .map(|(name, words, bytes)| {
            let chunks: Vec<String> = bytes
                .chunks(4 * words * CHUNK)
                .map(|c| hex(fnv1a64(c)))
                .collect();
            serde_json::json!({ "name": name, "words_per_pixel": words, "chunks": chunks })
        })
        .collect();
    let c = &image.meta.camera;
    let bits = |v: Vec3| v.to_array().map(f32::to_bits);
    let header = serde_json::json!({
        "version": 1,
        "width": image.width,
        "height": image.height,
        "camera": {
            "position": bits(c.position), "forward": bits(c.forward), "up": bits(c.up),
            "right": bits(c.right), "projection": "sphere", "vfov_deg": null, "window": c.window,
        },
        "time": image.meta.time.to_bits(),
        "scene": image.meta.scene,
        "image_fnv1a64": sum,
        "chunk_pixels": CHUNK,
        "planes": records,
    });
    let json = serde_json::to_vec(&header).unwrap();
    let mut out = b"RWPLANES".to_vec();
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(hex(fnv1a64(&json)).as_bytes());
    assert_eq!(n, image.radiance.len());
    for (_, _, bytes) in &planes {
        out.extend_from_slice(bytes);
    }
    out
}

#[test]
fn a_version_1_planes_file_still_reads_bit_for_bit_and_names_its_damage() {
    use rangewalk::image::planes_file;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("old.planes");
    let image = sample_image_of(Projection::Sphere, 300, 500);
    let mut bytes = version_1_planes(&image, "0123456789abcdef");
    std::fs::write(&path, &bytes).unwrap();
    assert_eq!(planes_file::read(&path, "0123456789abcdef").unwrap(), image);
    // The last byte: the last chunk of `normal`.
    *bytes.last_mut().unwrap() ^= 1;
    std::fs::write(&path, &bytes).unwrap();
    let e = format!(
        "{:#}",
        planes_file::read(&path, "0123456789abcdef").unwrap_err()
    );
    assert!(
        e.contains("chunk 2 of plane `normal`") && e.contains("damaged"),
        "{e}"
    );
}

#[test]
fn a_version_3_planes_file_round_trips_a_base_bit_for_bit_and_names_the_damaged_chunk() {
    use half::f16;
    use rangewalk::image::planes_file::{self, BasePlanes, CHUNK};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("b.planes");
    let sum = "0123456789abcdef";
    let base_of = |image: RangeImage| BasePlanes {
        width: image.width,
        height: image.height,
        radiance: image
            .radiance
            .iter()
            .map(|c| c.to_array().map(f16::from_f32))
            .collect(),
        scale: 0.25,
        distance: image.distance,
        object_id: image.object_id,
        primitive_id: image.primitive_id,
        normal: image.normal,
        meta: image.meta,
    };
    for projection in PROJECTIONS {
        let (image, _) = windowed_sample_image(projection);
        let base = base_of(image.clone());
        planes_file::write_base(&path, &base, sum).unwrap();
        assert_eq!(
            planes_file::read_base(&path, sum).unwrap(),
            base,
            "{projection:?}"
        );
        planes_file::verify(&path, sum).unwrap();
        // A range image is not what it holds, and a version-2 file holds
        // no base: each reader says which file it is given.
        let e = format!("{:#}", planes_file::read(&path, sum).unwrap_err());
        assert!(e.contains("b.planes") && e.contains("holds a base"), "{e}");
        let v2 = dir.path().join("v2.planes");
        planes_file::write(&v2, &image, sum).unwrap();
        let e = format!("{:#}", planes_file::read_base(&v2, sum).unwrap_err());
        assert!(e.contains("v2.planes") && e.contains("not a base"), "{e}");
    }
    // Three chunks a plane; a flipped bit in the second chunk of the
    // radiance is named while the other chunks read as written.
    let (w, h) = (300, 500);
    assert_eq!((w * h as usize).div_ceil(CHUNK), 3);
    let base = base_of(sample_image_of(Projection::Sphere, w as u32, h));
    planes_file::write_base(&path, &base, sum).unwrap();
    let file = planes_file::PlanesFile::open(&path, sum).unwrap();
    assert_eq!(file.version(), planes_file::VERSION);
    let halves: Vec<u8> = base.radiance[CHUNK..2 * CHUNK]
        .iter()
        .flatten()
        .flat_map(|h| h.to_bits().to_le_bytes())
        .collect();
    assert_eq!(file.read_chunk(0, 1).unwrap(), halves);
    let span = file.chunk_span(0, 1).unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[(span.start + span.end) as usize / 2] ^= 4;
    std::fs::write(&path, &bytes).unwrap();
    let e = format!("{:#}", planes_file::read_base(&path, sum).unwrap_err());
    assert!(
        e.contains("b.planes") && e.contains("chunk 1 of plane `radiance_half`"),
        "{e}"
    );
    assert!(planes_file::verify(&path, sum).is_err());
    let file = planes_file::PlanesFile::open(&path, sum).unwrap();
    let e = format!("{:#}", file.read_chunk(0, 1).unwrap_err());
    assert!(e.contains("chunk 1 of plane `radiance_half`"), "{e}");
    file.read_chunk(0, 0).unwrap();
    file.read_chunk(0, 2).unwrap();
}
