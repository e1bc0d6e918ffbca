//! What each fuzz target does with one input. The stable regression test
//! (`tests/fuzz_regressions.rs`) includes this file, so a saved input is
//! replayed through exactly the calls the fuzzer made.
//!
//! Every reader here takes paths, not bytes (they report errors by file
//! name), so an input is cut into files at [`SEPARATOR`] and written into
//! a scratch folder first.

use std::path::{Path, PathBuf};

use rangewalk::bake::{self, Bake, Manifest};
use rangewalk::image::exr_io;
use rangewalk::scene::Scene;

/// Cuts an input into its files. A comment line in TOML, OBJ and MTL, so
/// that a separator the fuzzer damages still leaves text the parsers read.
pub const SEPARATOR: &[u8] = b"\n#~~~~\n";

/// The names the scene target writes its parts to, in input order; seeds
/// name them (`mesh = "m.obj"`, `mtllib m.mtl`, `map_Kd t.png`).
pub const SCENE_FILES: [&str; 4] = ["scene.toml", "m.obj", "m.mtl", "t.png"];

/// The texture part is also written under these names, so that the reader
/// the extension picks can be any of the three.
const TEXTURE_COPIES: [&str; 2] = ["t.hdr", "t.exr"];

/// The base images the bake target writes after the manifest, as the
/// seeds' manifests name them.
pub const BAKE_IMAGES: usize = 4;

/// Images read per input at most: each costs a decode.
const MAX_IMAGES_READ: usize = 8;

/// The light layers a base image carries (`bake::DIRECT` and kin).
const LAYERS: [&str; 3] = [bake::DIRECT, bake::INDIRECT, bake::DIFFUSE_DIRECT];

/// The input's files, at most `n`: the last part keeps any further
/// separators.
pub fn split(data: &[u8], n: usize) -> Vec<&[u8]> {
    let mut parts = Vec::new();
    let mut rest = data;
    while parts.len() + 1 < n {
        match rest.windows(SEPARATOR.len()).position(|w| w == SEPARATOR) {
            Some(i) => {
                parts.push(&rest[..i]);
                rest = &rest[i + SEPARATOR.len()..];
            }
            None => break,
        }
    }
    parts.push(rest);
    parts
}

/// Joins files into one input, the inverse of [`split`].
pub fn join(parts: &[&[u8]]) -> Vec<u8> {
    parts.join(SEPARATOR)
}

/// Writes `files` into `dir`, removing the named files an input lacks so
/// that nothing of an earlier input is read.
fn write_files(dir: &Path, names: &[&str], parts: &[&[u8]]) {
    for (i, name) in names.iter().enumerate() {
        let path = dir.join(name);
        match parts.get(i) {
            Some(bytes) => std::fs::write(&path, bytes).expect("writing a scratch file"),
            None => {
                let _ = std::fs::remove_file(&path);
            }
        }
    }
}

/// The scene loader on a `scene.toml`, OBJ, MTL and texture.
pub fn scene(dir: &Path, data: &[u8]) -> Result<(), String> {
    let parts = split(data, SCENE_FILES.len());
    write_files(dir, &SCENE_FILES, &parts);
    let texture = parts.get(SCENE_FILES.len() - 1).copied();
    let copies: Vec<&[u8]> = texture.map_or(Vec::new(), |t| vec![t; TEXTURE_COPIES.len()]);
    write_files(dir, &TEXTURE_COPIES, &copies);
    let s = Scene::load(dir.join(SCENE_FILES[0])).map_err(|e| format!("{e:#}"))?;
    // What every command asks of a loaded scene first.
    let _ = s.geometry();
    let _ = s.bounds(s.animation.start);
    let _ = s.at(s.animation.end);
    Ok(())
}

/// The pure-Rust EXR reader as a range image, as a texture and as a base
/// image with light layers; `Ok` when the file is a range image.
pub fn exr(dir: &Path, data: &[u8]) -> Result<(), String> {
    let path = dir.join("image.exr");
    std::fs::write(&path, data).expect("writing a scratch file");
    let range = exr_io::read(&path).map(|_| ());
    let texture = exr_io::read_texture(&path).map(|_| ());
    // Only base images have the layers: a range image without them is no
    // error of the file's.
    let _ = exr_io::read_with_layers_hashed(&path, &LAYERS);
    range.and(texture).map_err(|e| format!("{e:#}"))
}

/// A scene for the bake target's manifests to match: their content hash
/// must be this scene's for the images to be read at all.
pub const BAKE_SCENE: &str = r#"[[materials]]
name = "grey"
type = "diffuse"
reflectance = [0.5, 0.5, 0.5]

[[objects]]
name = "quad"
mesh = "quad.obj"
material = "grey"

[[lights]]
type = "point"
position = [0.5, 0.5, -1]
intensity = [1, 1, 1]

[[cameras]]
name = "main"
position = [0.5, 0.5, -2]
look_at = [0.5, 0.5, 0]
vfov = 40

[view_space]
type = "segment"
a = [0.25, 0.5, -2]
b = [0.75, 0.5, -2]
"#;

pub const BAKE_MESH: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";

/// Writes [`BAKE_SCENE`] into `dir` and loads it.
pub fn bake_scene(dir: &Path) -> Scene {
    std::fs::write(dir.join("quad.obj"), BAKE_MESH).expect("writing the bake scene");
    let path = dir.join("scene.toml");
    std::fs::write(&path, BAKE_SCENE).expect("writing the bake scene");
    Scene::load(path).expect("the bake scene loads")
}

/// The bake directory's reader: a `manifest.json` and up to
/// [`BAKE_IMAGES`] images, opened against `scene`'s content hash, as
/// `synth`, `walk`, `view` and `bake --status` open it.
pub fn bake(dir: &Path, scene: &Scene, data: &[u8]) -> Result<(), String> {
    let images: Vec<String> = (0..BAKE_IMAGES).map(image_name).collect();
    let mut names = vec![bake::manifest::MANIFEST];
    names.extend(images.iter().map(String::as_str));
    std::fs::create_dir_all(dir.join(bake::manifest::IMAGES)).expect("creating a scratch folder");
    write_files(dir, &names, &split(data, names.len()));
    let status = bake::status::status(dir).map(|_| ());
    let opened = Manifest::read(dir).and_then(|_| {
        let bake = Bake::open(dir, scene)?;
        rangewalk::synth::check_bake(&bake)?;
        for k in 0..bake.manifest.images.len().min(MAX_IMAGES_READ) {
            // A damaged image is an error of its own; the others still read.
            let _ = bake.read(k);
        }
        Ok(())
    });
    status.and(opened).map_err(|e| format!("{e:#}"))
}

/// The file of base image `i` in the bake target's folder.
pub fn image_name(i: usize) -> String {
    format!("{}/{i}.exr", bake::manifest::IMAGES)
}

/// The saved inputs in `dir/kind` (`corpus` or `crashes`), in name order.
pub fn saved_inputs(dir: &Path, kind: &str) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir.join(kind))
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    files.retain(|p| p.is_file());
    files.sort();
    files
}
