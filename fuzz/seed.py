#!/usr/bin/env python3
"""Adds the fuzz targets' seed inputs to tests/fuzz-regressions/<target>/corpus/.

Run from the repository root after `cargo build --release` (the EXR and
bake seeds are files the renderer itself writes):

    python3 fuzz/seed.py target/release/rangewalk

An input is several files joined by SEPARATOR, as fuzz/src/lib.rs splits
them; keep the two in step.
"""

import hashlib
import pathlib
import re
import subprocess
import sys
import tempfile

SEPARATOR = b"\n#~~~~\n"
ROOT = pathlib.Path(__file__).resolve().parent.parent
OUT = ROOT / "tests" / "fuzz-regressions"


def save(target, parts):
    data = SEPARATOR.join(parts)
    d = OUT / target / "corpus"
    d.mkdir(parents=True, exist_ok=True)
    # libFuzzer names corpus files by their SHA-1; so do the seeds, so
    # that a merge never keeps the same input twice.
    (d / hashlib.sha1(data).hexdigest()).write_bytes(data)


def scene_seeds():
    """Bundled scenes with small meshes, and files as other tools write them."""
    for name in ["furnace", "cornell-box", "cornell-box-1e4", "glossy-sun"]:
        d = ROOT / "scenes" / name
        toml = (d / "scene.toml").read_text()
        meshes = set(re.findall(r'mesh = "([^"]+)"', toml))
        assert len(meshes) == 1, (name, meshes)
        obj = (d / meshes.pop()).read_bytes()
        toml = re.sub(r'mesh = "[^"]+"', 'mesh = "m.obj"', toml)
        save("scene", [toml.encode(), obj])
    w = ROOT / "tests" / "wavefront"
    obj = (w / "textured.obj").read_bytes().replace(b"textured.mtl", b"m.mtl")
    mtl = (w / "textured.mtl").read_bytes().replace(b"checker.png", b"t.png")
    toml = "".join(
        f'[[objects]]\nname = "{g}"\nmesh = "m.obj"\ngroup = "{g}"\n\n'
        for g in ["white", "wood", "tinted", "lost"]
    )
    png = (w / "checker.png").read_bytes()
    save("scene", [toml.encode(), obj, mtl, png])
    for mesh in ["plain.obj", "no-mtl-file.obj", "truncated.obj"]:
        save("scene", [b'[[objects]]\nname = "o"\nmesh = "m.obj"\n', (w / mesh).read_bytes()])
    # A textured [[materials]] entry, a glossy and a mirror one, every
    # light, a path and a view space, in one scene.
    toml = b'''[animation]
start = 0
end = 1
fps = 24

[[materials]]
name = "tex"
type = "diffuse"
reflectance = [0.5, 0.5, 0.5]
texture = "t.png"

[[materials]]
name = "shiny"
type = "glossy"
diffuse = [0.3, 0.3, 0.3]
specular = [0.2, 0.2, 0.2]
roughness = 0.2
model = "ward"

[[materials]]
name = "glass"
type = "mirror"
reflectance = [0.9, 0.9, 0.9]

[[objects]]
name = "a"
mesh = "m.obj"
material = "tex"
pivot = [0.5, 0.5, 0]
[[objects.keyframes]]
time = 0
[[objects.keyframes]]
time = 1
translate = [1, 0, 0]
rotate = { axis = [0, 0, 1], degrees = 90 }
scale = 2

[[objects]]
name = "b"
mesh = "m.obj"
material = "shiny"

[[lights]]
type = "point"
position = [0, 1, -1]
intensity = [1, 1, 1]

[[lights]]
type = "sun"
direction = [0, -1, 0.5]
radiance = [10, 10, 10]
angular_diameter = 0.5

[[cameras]]
name = "main"
position = [0.5, 0.5, -3]
look_at = [0.5, 0.5, 0]
vfov = 40

[view_space]
type = "box"
min = [0, 0, -3]
max = [1, 1, -2]

[[paths]]
name = "walk"
keys = [
  { time = 0, position = [0, 0.5, -3], direction = [0, 0, 1], vfov = 40 },
  { time = 1, position = [1, 0.5, -3], look_at = [0.5, 0.5, 0], up = [0, 1, 0], vfov = 50 },
]
'''
    obj = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n"
    save("scene", [toml, obj, b"", png])
    return toml, obj


def texture_seeds(rw, tmp, toml, obj):
    """The textured scene with a Radiance and an OpenEXR texture."""
    scene = ROOT / "scenes" / "cornell-box" / "scene.toml"
    run(rw, "render", scene, "--size", "3x2", "--spp", "1", "--out", tmp / "t.exr",
        "--hdr", tmp / "t.hdr")
    for ext in ["hdr", "exr"]:
        text = toml.replace(b'texture = "t.png"', f'texture = "t.{ext}"'.encode())
        save("scene", [text, obj, b"", (tmp / f"t.{ext}").read_bytes()])


def run(*args):
    subprocess.run([str(a) for a in args], check=True, stdout=subprocess.DEVNULL)


def exr_seeds(rw, tmp):
    """Range images of every projection, tiny, and the stored test image."""
    scene = ROOT / "scenes" / "cornell-box" / "scene.toml"
    for projection in ["perspective", "fisheye", "sphere"]:
        out = tmp / f"{projection}.exr"
        run(rw, "render", scene, "--size", "3x2", "--spp", "1", "--projection", projection,
            "--out", out)
        save("exr", [out.read_bytes()])
    save("exr", [(ROOT / "tests" / "image_io" / "sample-sphere.exr").read_bytes()])


def bake_seeds(rw, tmp):
    """A complete bake of the bake target's scene, its images renamed to
    the names the target writes them under."""
    lib = (ROOT / "fuzz" / "src" / "lib.rs").read_text()
    scene = re.search(r'BAKE_SCENE: &str = r#"(.*?)"#;', lib, re.S).group(1)
    mesh = re.search(r'BAKE_MESH: &str = "(.*?)";', lib).group(1).replace("\\n", "\n")
    (tmp / "scene.toml").write_text(scene)
    (tmp / "quad.obj").write_text(mesh)
    for indirect in ["path", "radiosity"]:
        bake = tmp / f"bake-{indirect}"
        run(rw, "bake", tmp / "scene.toml", "--quality", "0", "--size", "4", "--spp", "1",
            "--indirect", indirect, "--out", bake)
        manifest = (bake / "manifest.json").read_text()
        files = re.findall(r'"file": "([^"]+)"', manifest)
        images = []
        for i, f in enumerate(files[:4]):
            manifest = manifest.replace(f'"file": "{f}"', f'"file": "images/{i}.exr"')
            images.append((bake / f).read_bytes())
        save("bake", [manifest.encode()] + images)
        # A base image, with its light layers, for the EXR target too.
        save("exr", images[:1])


def main():
    rw = pathlib.Path(sys.argv[1]).resolve()
    toml, obj = scene_seeds()
    with tempfile.TemporaryDirectory() as tmp:
        texture_seeds(rw, pathlib.Path(tmp), toml, obj)
        exr_seeds(rw, pathlib.Path(tmp))
        bake_seeds(rw, pathlib.Path(tmp))


if __name__ == "__main__":
    main()
