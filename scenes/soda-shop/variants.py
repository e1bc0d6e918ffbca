#!/usr/bin/env python3
"""Small rooms cut from the soda shop, to take apart why its radiosity
records come out dark (docs/radiosity.md, Known gaps):

  bare          walls, wainscot, floor, ceiling and lamps; every material
                diffuse and untextured; the sun and the `main` camera
  rails         bare, with a chair rail of cherry along each wall: boxes
                6 cm tall and 3.5 cm deep, touching the wall
  white-rails   the rails as white as the wallpaper, with only their top,
                bottom and front faces
  tilted-rails  the white rails with their top and bottom faces tilted by
                1.6 degrees (1 mm across their depth), so that they no
                longer face exactly as the floor and the ceiling do

    python3 scenes/soda-shop/variants.py <out-dir>

writes one folder per room, each with its scene.toml; compare records with
a traced bounce in each with the records_against_traced example.
"""

import os
import shutil
import sys
import tomllib

HERE = os.path.dirname(os.path.abspath(__file__))
SHELL = ["wallpaper", "wainscot", "floor-light", "floor-dark", "ceiling", "lamp-cords", "lamp-glow"]
# Room: x 0..8, z 0..6; the chair rail's centre height (generate.py's RAIL).
LENGTH = {"x": 8.0, "z": 6.0}
RAIL, HALF, DEPTH = 1.0, 0.03, 0.035


def value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v + '"'
    if isinstance(v, list):
        return "[" + ", ".join(value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + " }"
    raise TypeError(v)


def table(header, entries):
    return f"{header}\n" + "".join(f"{k} = {value(v)}\n" for k, v in entries.items()) + "\n"


def diffuse(m):
    """The material as a plain diffuse one: glossy keeps its diffuse part,
    textures go; emission stays."""
    out = {"name": m["name"], "type": "diffuse"}
    if m["type"] == "glossy":
        out["reflectance"] = m["diffuse"]
    else:
        out["reflectance"] = m.get("reflectance", [0.5, 0.5, 0.5])
    if "emission" in m:
        out["emission"] = m["emission"]
    return out


def rail_faces(wall, white, tilt):
    """The quads of one chair rail: front, top and bottom, and for the
    cherry rails the back and the ends too."""
    y0, y1 = RAIL - HALF, RAIL + HALF
    # The front edges move out of the top's and bottom's planes.
    l = 0.001 if tilt else 0.0
    if wall in ("south", "north"):
        n, at, out = LENGTH["x"], (0.0 if wall == "south" else LENGTH["z"]), (1.0 if wall == "south" else -1.0)
    else:
        n, at, out = LENGTH["z"], (0.0 if wall == "west" else LENGTH["x"]), (1.0 if wall == "west" else -1.0)

    def p(s, y, d):
        """`s` along the wall, `d` out of it into the room."""
        w = at + out * d
        return (s, y, w) if wall in ("south", "north") else (w, y, s)

    f = DEPTH
    quads = [
        [p(0, y0 - l, f), p(n, y0 - l, f), p(n, y1 + l, f), p(0, y1 + l, f)],
        [p(0, y1 + l, f), p(n, y1 + l, f), p(n, y1, 0), p(0, y1, 0)],
        [p(0, y0, 0), p(n, y0, 0), p(n, y0 - l, f), p(0, y0 - l, f)],
    ]
    if not white:
        quads += [
            [p(0, y0, 0), p(0, y1, 0), p(n, y1, 0), p(n, y0, 0)],
            [p(0, y0, 0), p(0, y0 - l, f), p(0, y1 + l, f), p(0, y1, 0)],
            [p(n, y0, 0), p(n, y1, 0), p(n, y1 + l, f), p(n, y0 - l, f)],
        ]
    return quads


def rails_obj(white, tilt):
    lines, count = ["# Chair rails; see variants.py."], 0
    for wall in ("south", "north", "west", "east"):
        lines.append(f"o rail-{wall}")
        for quad in rail_faces(wall, white, tilt):
            for v in quad:
                lines.append("v %.6f %.6f %.6f" % v)
            k = count + 1
            lines.append(f"f {k} {k + 1} {k + 2}")
            lines.append(f"f {k} {k + 2} {k + 3}")
            count += 4
    return "\n".join(lines) + "\n"


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: variants.py <out-dir>")
    out = sys.argv[1]
    with open(os.path.join(HERE, "scene.toml"), "rb") as f:
        scene = tomllib.load(f)
    objects = [o for o in scene["objects"] if o["name"] in SHELL]
    missing = set(SHELL) - {o["name"] for o in objects}
    if missing:
        sys.exit(f"scene.toml has no objects named {sorted(missing)}")
    for name, rails in [("bare", None), ("rails", "cherry"), ("white-rails", "wallpaper"), ("tilted-rails", "wallpaper")]:
        d = os.path.join(out, name)
        os.makedirs(d, exist_ok=True)
        shutil.copy(os.path.join(HERE, "soda-shop.obj"), d)
        text = "# " + name + ": cut from the soda shop by variants.py.\n\n"
        text += table("[animation]", scene["animation"])
        for m in scene["materials"]:
            text += table("[[materials]]", diffuse(m))
        for o in objects:
            text += table("[[objects]]", o)
        if rails:
            with open(os.path.join(d, "rails.obj"), "w") as f:
                f.write(rails_obj(white=rails == "wallpaper", tilt=name == "tilted-rails"))
            for wall in ("south", "north", "west", "east"):
                o = {"name": f"rail-{wall}", "mesh": "rails.obj", "group": f"rail-{wall}", "material": rails}
                text += table("[[objects]]", o)
        for light in scene["lights"]:
            text += table("[[lights]]", light)
        for camera in scene["cameras"]:
            text += table("[[cameras]]", camera)
        with open(os.path.join(d, "scene.toml"), "w") as f:
            f.write(text)
        print(d)


if __name__ == "__main__":
    main()
