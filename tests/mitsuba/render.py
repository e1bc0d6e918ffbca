"""Render a Mitsuba 3 scene.xml with the scalar_rgb variant and write the
image as an OpenEXR file with Mitsuba's own writer.

usage: render.py SCENE_XML SEED OUT_EXR
"""
import sys
import time

import mitsuba as mi


def main() -> None:
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    scene_xml, seed, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    mi.set_variant("scalar_rgb")
    scene = mi.load_file(scene_xml)
    start = time.time()
    image = mi.render(scene, seed=seed)
    mi.Bitmap(image).write(out)
    print(f"{scene_xml}: seed {seed}, {time.time() - start:.2f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
