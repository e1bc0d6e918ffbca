#!/usr/bin/env python3
"""Writes soda-shop.obj and its textures (wallpaper.png, beadboard.png,
tin.png, ball.png): an old-fashioned soda shop with a counter, stools,
booths, tables, a soda fountain, shelves of bottles and glasses, a mirror,
pendant lamps and a ceiling fan.

Deterministic (fixed seed, fixed number formatting, fixed zlib level);
python3 standard library only. Units: metres, y up. The room spans x 0..8,
y 0..3.2, z 0..6; the shop windows are cut into the wall z = 0 and the sun
shines in through them. There is nothing outside (no ground, no sky), as in
the studio: exterior geometry would also enlarge the bounding box by which
the radiosity simplification sizes its patches. The counter runs along x in
front of the back bar on the wall z = 6; the booths stand against the wall
x = 8.

Groups with texture coordinates (wallpaper, wainscot, ceiling, ball) write
one `vt` per `v` and their faces as `f v/vt ...`, so that every vertex of
those groups has one. No two faces coincide (a box loses the faces it
stands on or that touch a wall): coincident faces made the radiosity solver
fail to converge, and overlays on large surfaces (raised panels, ceiling
bosses) hid them from its shadow rays, so detail there is in the textures.

The moving objects are modelled at their pose at t = 0; scene.toml moves
them (sliding_glass, spin_seat, fan_blades, ball) about the pivots printed
below.
Run from anywhere: python3 scenes/soda-shop/generate.py
"""

import math
import os
import random
import struct
import zlib

W, H, D = 8.0, 3.2, 6.0
REVEAL = 0.25  # wall thickness: depth of the window reveals, outwards
RAIL = 1.0  # height of the wainscot (chair rail); wallpaper above

# Pivots and start positions of the moving objects (scene.toml uses them).
GLASS_AT = (3.7, 1.05, 4.55)
SPIN_AT = (3.0, 0.0, 3.9)
FAN_AT = (4.0, 2.65, 1.0)
BALL_R = 0.14
BALL_AT = (5.0, BALL_R, 2.2)


class Obj:
    def __init__(self):
        self.lines = []
        self.nv = 0
        self.nvt = 0
        self.nt = 0
        self.vt_of = {}

    def group(self, name):
        self.lines.append(f"o {name}")

    def vert(self, p, uv=None):
        self.lines.append("v %.4f %.4f %.4f" % tuple(p))
        self.nv += 1
        if uv is not None:
            self.lines.append("vt %.4f %.4f" % tuple(uv))
            self.nvt += 1
            self.vt_of[self.nv] = self.nvt
        return self.nv

    def tri(self, a, b, c):
        if a in self.vt_of:
            t = self.vt_of
            self.lines.append(f"f {a}/{t[a]} {b}/{t[b]} {c}/{t[c]}")
        else:
            self.lines.append(f"f {a} {b} {c}")
        self.nt += 1

    def quad(self, a, b, c, d):
        self.tri(a, b, c)
        self.tri(a, c, d)

    def grid(self, origin, du, dv, nu, nv):
        """A parallelogram origin + s du + t dv cut into nu x nv quads;
        the front side faces du x dv."""
        idx = [[self.vert(add(origin, add(scale(du, i / nu), scale(dv, j / nv))))
                for j in range(nv + 1)] for i in range(nu + 1)]
        for i in range(nu):
            for j in range(nv):
                self.quad(idx[i][j], idx[i + 1][j], idx[i + 1][j + 1], idx[i][j + 1])

    def grid_uv(self, origin, du, dv, nu, nv, uv_of):
        """grid() with texture coordinates uv_of(point) at every vertex."""
        idx = []
        for i in range(nu + 1):
            row = []
            for j in range(nv + 1):
                p = add(origin, add(scale(du, i / nu), scale(dv, j / nv)))
                row.append(self.vert(p, uv_of(p)))
            idx.append(row)
        for i in range(nu):
            for j in range(nv):
                self.quad(idx[i][j], idx[i + 1][j], idx[i + 1][j + 1], idx[i][j + 1])

    def box(self, lo, hi, n=1, skip=()):
        """An axis-aligned box facing outwards, each face an n x n grid.
        Faces named in `skip` ("-x", "+y", ...) are left out, and so is a
        face lying on the floor (y = 0) or the ceiling (y = H): no face
        coincides with another, which would only hide light from the
        radiosity solver's shadow rays."""
        x0, y0, z0 = lo
        x1, y1, z1 = hi
        skip = set(skip) | ({"-y"} if y0 == 0 else set()) | ({"+y"} if y1 == H else set())
        ex, ey, ez = (x1 - x0, 0, 0), (0, y1 - y0, 0), (0, 0, z1 - z0)
        for name, origin, du, dv in (("-z", (x0, y0, z0), ey, ex), ("+z", (x0, y0, z1), ex, ey),
                                     ("-x", (x0, y0, z0), ez, ey), ("+x", (x1, y0, z0), ey, ez),
                                     ("-y", (x0, y0, z0), ex, ez), ("+y", (x0, y1, z0), ez, ex)):
            if name not in skip:
                self.grid(origin, du, dv, n, n)

    def obox(self, center, axes, half, n=1):
        """An oriented box: center + sum of s_i half_i axes_i, s_i in [-1, 1]."""
        a = [scale(ax, h) for ax, h in zip(axes, half)]
        o = add(center, scale(add(a[0], add(a[1], a[2])), -1))
        e = [scale(x, 2) for x in a]
        # Faces in pairs; the winding only matters for emitters.
        self.grid(o, e[1], e[0], n, n)
        self.grid(add(o, e[2]), e[0], e[1], n, n)
        self.grid(o, e[2], e[1], n, n)
        self.grid(add(o, e[0]), e[1], e[2], n, n)
        self.grid(o, e[0], e[2], n, n)
        self.grid(add(o, e[1]), e[2], e[0], n, n)

    def revolve(self, center, profile, segments, cap_bottom=True, cap_top=True):
        """A surface of revolution about the vertical axis through center:
        profile is a list of (radius, height) from bottom to top."""
        cx, cy, cz = center
        rings = []
        for r, h in profile:
            rings.append([self.vert((cx + r * math.cos(2 * math.pi * k / segments), cy + h,
                                     cz + r * math.sin(2 * math.pi * k / segments)))
                          for k in range(segments)])
        for a, b in zip(rings, rings[1:]):
            for k in range(segments):
                k1 = (k + 1) % segments
                self.quad(a[k], b[k], b[k1], a[k1])
        if cap_bottom:
            c = self.vert((cx, cy + profile[0][1], cz))
            for k in range(segments):
                self.tri(c, rings[0][k], rings[0][(k + 1) % segments])
        if cap_top:
            c = self.vert((cx, cy + profile[-1][1], cz))
            for k in range(segments):
                self.tri(c, rings[-1][(k + 1) % segments], rings[-1][k])

    def cylinder(self, base, radius, height, segments=24, rings=4):
        self.revolve(base, [(radius, height * i / rings) for i in range(rings + 1)], segments)

    def sphere(self, center, radius, segments, stacks):
        prof = [(radius * math.sin(math.pi * i / stacks), -radius * math.cos(math.pi * i / stacks))
                for i in range(1, stacks)]
        self.revolve(center, prof, segments)

    def uv_sphere(self, center, radius, segments, stacks):
        """A sphere with texture coordinates (u around y, v from the south
        pole up); the seam and the pole vertices are duplicated per column."""
        rows = []
        for j in range(1, stacks):
            th = math.pi * j / stacks
            rows.append([self.vert(add(center, (radius * math.sin(th) * math.cos(2 * math.pi * i / segments),
                                                -radius * math.cos(th),
                                                radius * math.sin(th) * math.sin(2 * math.pi * i / segments))),
                                   (i / segments, j / stacks))
                         for i in range(segments + 1)])
        for a, b in zip(rows, rows[1:]):
            for i in range(segments):
                self.quad(a[i], b[i], b[i + 1], a[i + 1])
        for i in range(segments):
            s = self.vert(add(center, (0, -radius, 0)), ((i + 0.5) / segments, 0.0))
            self.tri(s, rows[0][i], rows[0][i + 1])
            n = self.vert(add(center, (0, radius, 0)), ((i + 0.5) / segments, 1.0))
            self.tri(n, rows[-1][i + 1], rows[-1][i])

    def tube(self, points, radius, sides=12, closed=False, caps=True):
        """A tube of constant radius along a polyline (parallel-transported
        frame); `closed` joins the last point to the first."""
        n = len(points)
        tang = []
        for i in range(n):
            if closed:
                a, b = points[(i - 1) % n], points[(i + 1) % n]
            else:
                a, b = points[max(i - 1, 0)], points[min(i + 1, n - 1)]
            tang.append(norm(sub(b, a)))
        t0 = tang[0]
        u = norm(cross(t0, (0, 1, 0) if abs(t0[1]) < 0.9 else (1, 0, 0)))
        rings = []
        for i in range(n):
            t = tang[i]
            u = norm(sub(u, scale(t, dot(u, t))))
            v = cross(t, u)
            rings.append([self.vert(add(points[i], add(scale(u, radius * math.cos(2 * math.pi * k / sides)),
                                                       scale(v, radius * math.sin(2 * math.pi * k / sides)))))
                          for k in range(sides)])
        pairs = list(zip(rings, rings[1:])) + ([(rings[-1], rings[0])] if closed else [])
        for r0, r1 in pairs:
            for k in range(sides):
                k1 = (k + 1) % sides
                self.quad(r0[k], r0[k1], r1[k1], r1[k])
        if caps and not closed:
            for ring, p in ((rings[0], points[0]), (rings[-1], points[-1])):
                c = self.vert(p)
                for k in range(sides):
                    self.tri(c, ring[k], ring[(k + 1) % sides])

    def torus(self, center, big, small, nu, nv):
        pts = [add(center, (big * math.cos(2 * math.pi * i / nu), 0, big * math.sin(2 * math.pi * i / nu)))
               for i in range(nu)]
        self.tube(pts, small, nv, closed=True)


def add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def scale(a, s):
    return tuple(x * s for x in a)


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def norm(a):
    n = math.sqrt(sum(c * c for c in a))
    return tuple(c / n for c in a)


def refine(xs, cell):
    out = [xs[0]]
    for a, b in zip(xs, xs[1:]):
        n = max(1, math.ceil((b - a) / cell - 1e-9))
        out += [a + (b - a) * k / n for k in range(1, n + 1)]
    return out


# The four walls: origin, du (along the wall), dv (= +y), length; du x dv
# faces into the room.
WALLS = {
    "south": ((0, 0, 0), (1, 0, 0), W),
    "west": ((0, 0, D), (0, 0, -1), D),
    "north": ((W, 0, D), (-1, 0, 0), W),
    "east": ((W, 0, 0), (0, 0, 1), D),
}


def inward(du):
    return cross(du, (0, 1, 0))


def wall_region(o, wall, v_lo, v_hi, holes, cell, uv_repeat=None):
    """The part v_lo <= v <= v_hi of a wall, with rectangular holes
    (u0, v0, u1, v1), cut into cells no larger than `cell` so that shared
    edges line up. With uv_repeat, texture coordinates (u, v) / uv_repeat."""
    origin, du, length = WALLS[wall]
    dv = (0, 1, 0)
    us = {0.0, length}
    vs = {v_lo, v_hi}
    for u0, v0, u1, v1 in holes:
        us |= {u0, u1}
        vs |= {min(max(v0, v_lo), v_hi), min(max(v1, v_lo), v_hi)}
    us, vs = refine(sorted(us), cell), refine(sorted(vs), cell)
    idx = {}

    def vid(i, j):
        if (i, j) not in idx:
            p = add(origin, add(scale(du, us[i]), scale(dv, vs[j])))
            uv = None if uv_repeat is None else (us[i] / uv_repeat, vs[j] / uv_repeat)
            idx[(i, j)] = o.vert(p, uv)
        return idx[(i, j)]

    for i in range(len(us) - 1):
        for j in range(len(vs) - 1):
            mu, mv = (us[i] + us[i + 1]) / 2, (vs[j] + vs[j + 1]) / 2
            if any(u0 < mu < u1 and v0 < mv < v1 for u0, v0, u1, v1 in holes):
                continue
            o.quad(vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1))


def wall_point(wall, u, v, w=0.0):
    """A point u along the wall, at height v, w into the room."""
    origin, du, _ = WALLS[wall]
    return add(origin, add(scale(du, u), add((0, v, 0), scale(inward(du), w))))


# The face of a box against each wall (w = 0).
BACK_FACE = {"south": "-z", "west": "-x", "north": "+z", "east": "+x"}


def wall_box(o, wall, u0, v0, u1, v1, w0, w1, n=1):
    """An axis-aligned box on a wall: u0..u1 along it, v0..v1 high, w0..w1
    into the room; without its back face when it stands on the wall."""
    a, b = wall_point(wall, u0, v0, w0), wall_point(wall, u1, v1, w1)
    o.box(tuple(map(min, a, b)), tuple(map(max, a, b)), n, (BACK_FACE[wall],) if w0 == 0 else ())


def window(o, wall, u0, v0, u1, v1):
    """The four reveal faces of a window hole, reaching REVEAL outwards."""
    origin, du, _ = WALLS[wall]
    dv, out = (0, 1, 0), scale(inward(du), -1)
    p = lambda u, v: add(origin, add(scale(du, u), scale(dv, v)))
    o.grid(p(u0, v0), scale(out, REVEAL), scale(du, u1 - u0), 1, 8)   # sill
    o.grid(p(u0, v1), scale(du, u1 - u0), scale(out, REVEAL), 8, 1)   # head
    o.grid(p(u0, v0), scale(dv, v1 - v0), scale(out, REVEAL), 6, 1)   # left jamb
    o.grid(p(u1, v0), scale(out, REVEAL), scale(dv, v1 - v0), 1, 6)   # right jamb


def mullions(o, wall, u0, v0, u1, v1, nu, w=0.05):
    """nu - 1 upright bars and a transom at 3/4 height, in the reveal."""
    c = -REVEAL / 2
    for k in range(1, nu):
        um = u0 + (u1 - u0) * k / nu
        wall_box(o, wall, um - w / 2, v0, um + w / 2, v1, c - w / 2, c + w / 2, 2)
    vt = v0 + 0.75 * (v1 - v0)
    wall_box(o, wall, u0, vt - w / 2, u1, vt + w / 2, c - w / 2, c + w / 2, 2)


def png(path, rows):
    """An 8-bit RGB PNG from rows of (r, g, b) tuples (zlib level 9)."""
    h, w = len(rows), len(rows[0])
    raw = b"".join(b"\x00" + bytes(c for px in row for c in px) for row in rows)

    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(raw, 9)))
        f.write(chunk(b"IEND", b""))


def wallpaper_texture():
    """64 x 64 vertical stripes: cream with a sage stripe and pin lines."""
    cream, sage, pin = (236, 226, 198), (172, 200, 170), (150, 60, 55)
    row = []
    for x in range(64):
        k = x % 16
        row.append(sage if 9 <= k <= 14 else pin if k in (8, 15) else cream)
    return [row[:] for _ in range(64)]


def beadboard_texture():
    """64 x 64 vertical boards of cherry wood with dark grooves and a
    slight grain, for the wainscot."""
    rows = []
    for y in range(64):
        row = []
        for x in range(64):
            k = x % 16
            if k == 0:
                row.append((92, 58, 40))
            elif k == 1:
                row.append((170, 120, 92))
            else:
                g = 6 * math.sin(2 * math.pi * (y / 32 + 0.13 * (x // 16)) + 0.7 * k)
                row.append((int(150 + g), int(104 + g * 0.7), int(76 + g * 0.5)))
        rows.append(row)
    return rows


def tin_texture():
    """64 x 64 pressed-tin ceiling tile: a raised square frame, a disc in
    the middle, on a cream ground."""
    rows = []
    for y in range(64):
        row = []
        for x in range(64):
            dx, dy = abs(x - 31.5), abs(y - 31.5)
            r = math.hypot(x - 31.5, y - 31.5)
            if max(dx, dy) > 29:
                c = (200, 196, 182)
            elif max(dx, dy) > 26:
                c = (240, 236, 222)
            elif r < 9:
                c = (246, 242, 228) if r < 7 else (196, 192, 178)
            elif abs(dx - dy) < 1.5 and r < 24:
                c = (214, 210, 196)
            else:
                c = (236, 232, 218)
            row.append(c)
        rows.append(row)
    return rows


def ball_texture():
    """64 x 64: 8 x 4 checker of red and cream (on the ball's u, v)."""
    red, cream = (205, 38, 30), (238, 228, 205)
    return [[red if (x // 8 + y // 16) % 2 else cream for x in range(64)] for y in range(64)]


def stool_base(o, x, z):
    """The chrome parts of a counter stool: foot, pole, footrest ring."""
    o.revolve((x, 0, z), [(0.2, 0.0), (0.2, 0.015), (0.16, 0.03), (0.06, 0.05), (0.035, 0.07)], 48, False, False)
    o.cylinder((x, 0.07, z), 0.03, 0.62, 24, 6)
    o.torus((x, 0.3, z), 0.17, 0.012, 40, 8)
    for k in range(4):
        a = 2 * math.pi * (k + 0.5) / 4
        o.tube([(x + 0.03 * math.cos(a), 0.3, z + 0.03 * math.sin(a)),
                (x + 0.17 * math.cos(a), 0.3, z + 0.17 * math.sin(a))], 0.008, 8)
    # chrome rim under the seat
    o.revolve((x, 0.69, z), [(0.06, 0.0), (0.185, 0.02), (0.19, 0.04)], 48, True, False)


def stool_seat(o, x, z):
    """The red vinyl cushion, 0.73..0.80 high."""
    prof = [(0.19, 0.0)] + [(0.19 + 0.012 * math.sin(math.pi * i / 6), 0.035 * i / 6) for i in range(1, 7)]
    prof += [(0.19 - 0.03 * (1 - math.cos(0.5 * math.pi * i / 5)), 0.035 + 0.035 * math.sin(0.5 * math.pi * i / 5))
             for i in range(1, 6)]
    o.revolve((x, 0.73, z), prof, 48, True, True)


def spin_backrest(o, x, z):
    """A low curved back pad on the -z side of the spinning seat (the
    counter is at +z), on two uprights."""
    n = 12
    for i in range(n):
        a = math.pi * (1.25 + 0.5 * (i + 0.5) / n)
        c = (x + 0.17 * math.cos(a), 1.02, z + 0.17 * math.sin(a))
        t = (-math.sin(a), 0, math.cos(a))
        r = (math.cos(a), 0, math.sin(a))
        o.obox(c, (t, (0, 1, 0), r), (0.17 * 0.5 * math.pi / n / 2 + 0.003, 0.08, 0.02), 2)
    for a in (math.pi * 1.35, math.pi * 1.65):
        o.tube([(x + 0.17 * math.cos(a), 0.78, z + 0.17 * math.sin(a)),
                (x + 0.17 * math.cos(a), 0.95, z + 0.17 * math.sin(a))], 0.012, 10)


def parlour_chair(o, x, z, facing):
    """A wire ice-cream-parlour chair, seat 0.46 high, its back on the side
    away from `facing` (an angle in radians about y the sitter looks to)."""
    ca, sa = math.cos(facing), math.sin(facing)
    rot = lambda px, py, pz: (x + ca * px - sa * pz, py, z + sa * px + ca * pz)
    # The sitter looks along +px; the back is at px = -0.18.
    o.revolve((x, 0.44, z), [(0.2, 0.0), (0.2, 0.03)], 40, True, True)
    for k in range(4):
        a = 2 * math.pi * (k + 0.5) / 4
        top = rot(0.15 * math.cos(a), 0.44, 0.15 * math.sin(a))
        mid = rot(0.18 * math.cos(a), 0.2, 0.18 * math.sin(a))
        bot = rot(0.21 * math.cos(a), 0.0, 0.21 * math.sin(a))
        o.tube([top, mid, bot], 0.01, 8)
    o.tube([rot(0.17 * math.cos(a), 0.2, 0.17 * math.sin(a))
            for a in [2 * math.pi * i / 24 for i in range(24)]], 0.006, 6, closed=True)
    # The back: two uprights bent into a loop ("heart" back), in the plane px = -0.18.
    pts = []
    for i in range(33):
        a = 2 * math.pi * i / 32
        pts.append(rot(-0.18 - 0.02 * math.sin(a / 2), 0.72 + 0.2 * math.sin(a) * 0.9, 0.16 * math.cos(a)))
    o.tube(pts, 0.008, 6)
    for s in (-1, 1):
        o.tube([rot(-0.18, 0.47, 0.15 * s), rot(-0.18, 0.72, 0.16 * s)], 0.009, 8)


def round_table(o, tops, x, z, r=0.36):
    """A pedestal table: a marble top in `tops`, the iron foot in o."""
    o.revolve((x, 0, z), [(0.25, 0.0), (0.25, 0.02), (0.12, 0.05), (0.04, 0.1)], 40, False, False)
    o.cylinder((x, 0.1, z), 0.03, 0.62, 20, 6)
    o.revolve((x, 0.7, z), [(0.04, 0.0), (0.15, 0.02)], 40, True, True)
    tops.append(("round", x, z, r))


def bottle(o, x, y, z, h, rng):
    """A bottle about h high: body, shoulder, neck, lip."""
    r = 0.03 + 0.008 * rng.random()
    neck = 0.011
    prof = [(r * 0.92, 0.0), (r, 0.01)]
    prof += [(r, 0.01 + (0.55 * h - 0.01) * i / 3) for i in range(1, 4)]
    for i in range(1, 6):
        a = 0.5 * math.pi * i / 5
        prof.append((neck + (r - neck) * math.cos(a), 0.55 * h + 0.2 * h * math.sin(a)))
    prof += [(neck, 0.93 * h), (neck * 1.3, 0.95 * h), (neck * 1.3, h)]
    o.revolve((x, y, z), prof, 16, True, True)


def tumbler(o, x, y, z, h=0.12, r=0.032):
    """An open flared glass with a wall thickness."""
    out = [(r * 0.85 + 0.15 * r * i / 4, h * i / 4) for i in range(5)]
    inn = [(r * 0.95 - 0.1 * r * i / 3, h - (h - 0.012) * i / 3) for i in range(4)]
    o.revolve((x, y, z), out + inn, 16, True, True)


def sundae_glass(o, x, y, z):
    """A tulip glass on a stem."""
    prof = [(0.035, 0.0), (0.035, 0.004), (0.01, 0.01), (0.006, 0.03), (0.006, 0.06)]
    prof += [(0.006 + 0.04 * math.sin(0.5 * math.pi * i / 7), 0.06 + 0.1 * i / 7) for i in range(1, 8)]
    prof += [(0.05, 0.18), (0.043, 0.18), (0.04, 0.12)]
    o.revolve((x, y, z), prof, 20, True, True)


def soda_glass(o, x, y, z):
    """The tall flared soda glass that slides along the counter, with a straw."""
    prof = [(0.03, 0.0), (0.032, 0.01), (0.025, 0.02)]
    prof += [(0.025 + 0.02 * (i / 10) ** 1.5, 0.02 + 0.2 * i / 10) for i in range(1, 11)]
    prof += [(0.041, 0.22), (0.038, 0.2), (0.03, 0.1), (0.022, 0.03)]
    o.revolve((x, y, z), prof, 32, True, True)
    o.tube([(x + 0.01, y + 0.05, z), (x + 0.025, y + 0.28, z), (x + 0.04, y + 0.3, z + 0.01),
            (x + 0.06, y + 0.3, z + 0.02)], 0.004, 8)


def fountain(o, x, z, y=1.05):
    """A chrome soda fountain on the counter: a fluted column with a dome,
    three goose-neck spouts towards the customer (-z), a drip tray."""
    prof = [(0.14, 0.0), (0.14, 0.02), (0.11, 0.04), (0.09, 0.08)]
    prof += [(0.085 + 0.004 * math.cos(8 * math.pi * i / 20), 0.08 + 0.4 * i / 20) for i in range(1, 21)]
    prof += [(0.11, 0.5), (0.11, 0.53)]
    prof += [(0.11 * math.cos(0.5 * math.pi * i / 10), 0.53 + 0.09 * math.sin(0.5 * math.pi * i / 10))
             for i in range(1, 10)]
    o.revolve((x, y, z), prof, 64, True, True)
    o.sphere((x, y + 0.65, z), 0.025, 16, 8)
    for k, a in enumerate((-0.55, 0.0, 0.55)):
        dx, dz = math.sin(a), -math.cos(a)
        pts = []
        for i in range(25):
            s = i / 24
            ang = math.pi * s
            reach = 0.08 + 0.12 * (1 - math.cos(ang)) / 2 + 0.04 * s
            hgt = 0.42 + 0.06 * math.sin(ang) - 0.12 * s * s
            pts.append((x + dx * reach, y + hgt, z + dz * reach))
        o.tube(pts, 0.011, 12)
        # the tap handle on top of the spout's root
        hx, hz = x + dx * 0.13, z + dz * 0.13
        o.tube([(hx, y + 0.47, hz), (hx, y + 0.56, hz)], 0.006, 8)
        o.sphere((hx, y + 0.575, hz), 0.016, 16, 8)
    o.box((x - 0.26, y, z - 0.28), (x + 0.26, y + 0.02, z - 0.1), 6, ("-y",))


def fan_blade(o, c, angle, pitch=0.25):
    """One blade of the ceiling fan: a thin board turned by `angle` about
    y and pitched about its long axis."""
    ca, sa = math.cos(angle), math.sin(angle)
    ax = (ca, 0, sa)
    side = (-sa, 0, ca)
    cp, sp = math.cos(pitch), math.sin(pitch)
    wdir = add(scale(side, cp), (0, sp, 0))
    tdir = cross(ax, wdir)
    o.obox(add(c, scale(ax, 0.42)), (ax, wdir, tdir), (0.28, 0.08, 0.006), 6)
    o.obox(add(c, scale(ax, 0.14)), (ax, side, (0, 1, 0)), (0.07, 0.015, 0.006), 2)


def pendant(o, shades, glows, x, z, drop=0.8):
    """A pendant lamp: cord (in o), a conical shade (shades) and the opal
    glass globe hanging just below the shade's rim (glows), which lights the
    whole room, ceiling included, rather than only the counter under it."""
    y = H - drop
    o.tube([(x, H, z), (x, y + 0.22, z)], 0.005, 8)
    prof = [(0.2, 0.0), (0.205, 0.005)]
    prof += [(0.2 - 0.15 * math.sin(0.5 * math.pi * i / 10), 0.005 + 0.2 * (1 - math.cos(0.5 * math.pi * i / 10)))
             for i in range(1, 11)]
    prof += [(0.03, 0.22)]
    shades.append(((x, y, z), prof))
    glows.append((x, y - 0.2, z, 0.16))


def main():
    rng = random.Random(1955)
    o = Obj()
    o.lines.append("# Soda shop for the walk-through experiment; see generate.py.")
    here = os.path.dirname(os.path.abspath(__file__))

    # Window holes (u0, v0, u1, v1) in wall coordinates: two shop windows and
    # a small one above the first booth.
    south = [(0.8, RAIL, 3.2, 2.7), (4.2, RAIL, 6.2, 2.7), (6.85, 1.35, 7.75, 2.55)]
    o.group("wallpaper")
    for wall in ("south", "west", "north", "east"):
        holes = south if wall == "south" else []
        wall_region(o, wall, RAIL, H, holes, 0.4, uv_repeat=0.5)
    o.group("wainscot")
    for wall in ("south", "west", "north", "east"):
        wall_region(o, wall, 0.0, RAIL, [], 0.4, uv_repeat=0.4)
    o.group("window_frames")
    for u0, v0, u1, v1 in south:
        window(o, "south", u0, v0, u1, v1)
        mullions(o, "south", u0, v0, u1, v1, 3 if u1 - u0 > 1.5 else 2)
        wall_box(o, "south", u0 - 0.06, v1, u1 + 0.06, v1 + 0.08, 0, 0.03, 2)  # head casing
        wall_box(o, "south", u0 - 0.06, v0 - 0.04, u1 + 0.06, v0, 0, 0.06, 2)  # sill board
        for uu in (u0 - 0.06, u1):
            wall_box(o, "south", uu, v0, uu + 0.06, v1, 0, 0.03, 2)

    o.group("panelling")
    for wall in ("south", "west", "north", "east"):
        _, _, length = WALLS[wall]
        wall_box(o, wall, 0, RAIL - 0.03, length, RAIL + 0.03, 0, 0.035, 2)  # chair rail
        wall_box(o, wall, 0, 0, length, 0.14, 0, 0.02, 2)  # skirting
        wall_box(o, wall, 0, H - 0.12, length, H, 0, 0.08, 2)  # cornice

    o.group("floor_light")
    light_tiles, dark_tiles = [], []
    tile = 0.4
    for i in range(int(W / tile)):
        for j in range(int(D / tile)):
            (light_tiles if (i + j) % 2 == 0 else dark_tiles).append((i * tile, j * tile))
    for x, z in light_tiles:
        o.grid((x, 0, z), (0, 0, tile), (tile, 0, 0), 3, 3)
    o.group("floor_dark")
    for x, z in dark_tiles:
        o.grid((x, 0, z), (0, 0, tile), (tile, 0, 0), 3, 3)

    # The pressed-tin ceiling is a texture: raised bosses of their own would
    # hide most of the flat ceiling from the radiosity solver.
    o.group("ceiling")
    o.grid_uv((0, H, 0), (W, 0, 0), (0, 0, D), 32, 24, lambda p: (p[0] / 0.6, p[2] / 0.6))

    # The counter: body, marble top, chrome kick plate and trim.
    cx0, cx1, cz0, cz1 = 0.9, 6.1, 4.35, 4.9
    o.group("counter_front")
    o.box((cx0, 0.0, cz0), (cx1, 0.98, cz1), 16, ("+y",))
    o.group("counter_top")
    o.box((cx0 - 0.06, 0.98, cz0 - 0.1), (cx1 + 0.06, 1.05, cz1 + 0.02), 12)

    # The back bar on the north wall: cabinet, marble top, mirror, shelves.
    bz0 = 5.45
    o.group("back_bar")
    o.box((0.6, 0, bz0), (6.4, 0.95, D), 12, ("+z", "+y"))
    # mirror frame and the columns between mirror and shelves
    mx0, mx1, my0, my1 = 2.0, 5.0, 1.2, 2.4
    o.box((mx0 - 0.08, my0 - 0.08, D - 0.04), (mx1 + 0.08, my0, D), 4, ("+z",))
    o.box((mx0 - 0.08, my1, D - 0.04), (mx1 + 0.08, my1 + 0.08, D), 4, ("+z",))
    for xx in (mx0 - 0.08, mx1):
        o.box((xx, my0, D - 0.04), (xx + 0.08, my1, D), 4, ("+z",))
    for xx in (0.6, 1.92, 5.0, 6.32):
        o.box((xx, 0.99, D - 0.32), (xx + 0.08, 2.75, D), 4, ("+z",))
    o.box((0.6, 2.75, D - 0.36), (6.4, 2.85, D), 8, ("+z",))  # entablature
    shelf_ys = (1.3, 1.72, 2.14)
    for xa, xb in ((0.68, 1.92), (5.08, 6.32)):
        for y in shelf_ys:
            o.box((xa, y - 0.025, D - 0.3), (xb, y, D), 4, ("+z",))
    o.group("back_bar_top")
    o.box((0.58, 0.95, bz0 - 0.04), (6.42, 0.99, D), 12, ("+z",))
    o.group("mirror")
    o.grid((mx1, my0, D - 0.02), (0, my1 - my0, 0), (mx0 - mx1, 0, 0), 1, 1)

    # Bottles on the side shelves (three colours) and glasses.
    bottles = {"bottles_green": [], "bottles_amber": [], "bottles_clear": []}
    glasses = []
    for xa, xb in ((0.68, 1.92), (5.08, 6.32)):
        for s, y in enumerate((0.99,) + shelf_ys):
            if s == 0:
                continue  # the back bar top holds glasses, below
            x = xa + 0.06
            while x < xb - 0.05:
                if s == 3:
                    glasses.append(("tumbler", x, y, D - 0.17))
                    x += 0.085
                    continue
                kind = sorted(bottles)[rng.randrange(3)]
                h = 0.26 + 0.08 * rng.random() if s < 2 else 0.24 + 0.06 * rng.random()
                bottles[kind].append((x, y, D - 0.15 - 0.03 * rng.random(), h))
                x += 0.085 + 0.01 * rng.random()
    # sundae glasses and tumblers along the back bar, in front of the mirror
    for k in range(22):
        x = 2.1 + 2.8 * k / 21
        glasses.append(("sundae" if k % 2 == 0 else "tumbler", x, 0.99, D - 0.2))
    for k in range(10):
        glasses.append(("tumbler", 0.75 + 0.11 * k, 0.99, D - 0.35))
        glasses.append(("tumbler", 5.2 + 0.11 * k, 0.99, D - 0.35))
    # glasses and jars on the counter
    for x in (1.3, 1.45, 5.85):
        glasses.append(("sundae", x, 1.05, 4.75))
    for name in sorted(bottles):
        o.group(name)
        for x, y, z, h in bottles[name]:
            bottle(o, x, y, z, h, rng)
    o.group("glasses")
    for kind, x, y, z in glasses:
        if kind == "sundae":
            sundae_glass(o, x, y, z)
        else:
            tumbler(o, x, y, z)
    o.group("jars")
    for x in (1.8, 2.0, 2.2):
        o.revolve((x, 1.05, 4.72), [(0.06, 0.0), (0.065, 0.01), (0.065, 0.2), (0.05, 0.23), (0.05, 0.25),
                                    (0.055, 0.255), (0.055, 0.27)], 32, True, True)
    o.group("jar_lids")
    for x in (1.8, 2.0, 2.2):
        o.revolve((x, 1.32, 4.72), [(0.058, 0.0), (0.058, 0.02), (0.04, 0.035), (0.012, 0.04),
                                    (0.012, 0.06)], 32, True, True)
        o.sphere((x, 1.39, 4.72), 0.014, 12, 6)

    o.group("fountain")
    fountain(o, 2.7, 4.62)
    # napkin holders and a milk-shake mixer on the counter, also chrome
    for x in (1.1, 4.9, 5.7):
        o.box((x - 0.06, 1.05, 4.5), (x + 0.06, 1.15, 4.56), 4, ("-y",))
    o.revolve((5.3, 1.05, 4.75), [(0.09, 0.0), (0.09, 0.03), (0.05, 0.06), (0.04, 0.4), (0.06, 0.42),
                                   (0.06, 0.47), (0.02, 0.5)], 40, True, True)
    o.tube([(5.3, 1.35, 4.75), (5.3, 1.35, 4.67), (5.3, 1.2, 4.62)], 0.008, 8)
    o.revolve((5.3, 1.1, 4.62), [(0.04, 0.0), (0.05, 0.15)], 32, True, False)

    # Stools in front of the counter; the one at SPIN_AT turns.
    stool_xs = [1.4, 2.2, 3.0, 3.8, 4.6, 5.4]
    o.group("stool_chrome")
    for x in stool_xs:
        stool_base(o, x, SPIN_AT[2])
    o.group("stool_seats")
    for x in stool_xs:
        if x != SPIN_AT[0]:
            stool_seat(o, x, SPIN_AT[2])
    o.group("spin_seat")
    stool_seat(o, SPIN_AT[0], SPIN_AT[2])
    spin_backrest(o, SPIN_AT[0], SPIN_AT[2])

    # Booths against the east wall: two tables between high-backed benches.
    o.group("booth_wood")
    cushions = []
    tops = []
    for b0 in (0.3, 2.35):
        for zs, back in ((b0, -1), (b0 + 1.4, 1)):
            # A wooden base, the upholstered seat and back on it (no faces
            # between them) and a wooden cap on the back.
            z0, z1 = zs, zs + 0.5
            o.box((6.6, 0, z0), (W, 0.4, z1), 6, ("+x", "+y"))
            zb = z0 if back < 0 else z1 - 0.12
            o.box((6.58, 1.3, zb - 0.01), (W, 1.36, zb + 0.13), 4, ("+x",))
            cushions.append(((6.6, 0.4, zb), (W, 1.3, zb + 0.12), ("+x", "-y", "+y")))
            cushions.append(((6.6, 0.4, zb + 0.12 if back < 0 else z0), (W, 0.5, z1 if back < 0 else zb),
                             ("+x", "-y")))
        # table between the benches: pedestal and top
        tz = b0 + 0.95
        o.revolve((7.35, 0, tz), [(0.2, 0.0), (0.2, 0.02)], 32, False, True)
        o.cylinder((7.35, 0.02, tz), 0.04, 0.7, 20, 6)
        tops.append(("rect", 6.75, tz - 0.33, W - 0.01, tz + 0.33))
    o.group("booth_vinyl")
    for lo, hi, skip in cushions:
        o.box(lo, hi, 6, skip)

    # Parlour tables and chairs by the west wall and the window.
    o.group("table_iron")
    for x, z in ((1.1, 1.3), (1.1, 2.9), (2.4, 0.75)):
        round_table(o, tops, x, z)
    o.group("table_tops")
    for t in tops:
        if t[0] == "round":
            _, x, z, r = t
            o.revolve((x, 0.72, z), [(r - 0.01, 0.0), (r, 0.01), (r, 0.03), (r - 0.01, 0.04)], 48, True, True)
        else:
            _, x0, z0, x1, z1 = t
            o.box((x0, 0.72, z0), (x1, 0.76, z1), 8)
    o.group("chairs")
    for x, z, facing in ((0.45, 1.3, 0.0), (1.75, 1.3, math.pi), (0.45, 2.9, 0.0), (1.75, 2.9, math.pi),
                         (1.1, 2.25, 0.5 * math.pi), (2.4, 1.4, -0.5 * math.pi), (1.75, 0.6, 0.2)):
        parlour_chair(o, x, z, facing)

    # A jukebox in the north-east corner.
    o.group("jukebox")
    o.box((7.05, 0, 5.35), (7.85, 1.1, 5.95), 8, ("+y",))
    o.tube([(7.45, 1.1, 5.35), (7.45, 1.1, 5.95)], 0.4, 48)
    o.group("jukebox_trim")
    o.box((7.12, 0.55, 5.33), (7.78, 0.95, 5.35), 4, ("+z",))
    o.tube([(7.45 + 0.36 * math.cos(a), 1.1 + 0.36 * math.sin(a), 5.33)
            for a in [math.pi * i / 24 for i in range(25)]], 0.015, 8)

    # Pendant lamps over the counter.
    shades, glows = [], []
    o.group("lamp_cords")
    for x in (1.8, 3.5, 5.2):
        pendant(o, shades, glows, x, 4.6)
    o.group("lamp_shades")
    for c, prof in shades:
        o.revolve(c, prof, 48, False, True)
    o.group("lamp_glow")
    for x, y, z, r in glows:
        o.uv_sphere((x, y, z), r, 32, 16)

    # Ceiling fan: downrod and motor (static), blades (turning).
    fx, fy, fz = FAN_AT
    o.group("fan_motor")
    o.cylinder((fx, fy + 0.1, fz), 0.012, H - fy - 0.1, 12, 2)
    o.revolve((fx, H - 0.05, fz), [(0.07, 0.0), (0.07, 0.05)], 32, True, False)
    o.revolve((fx, fy - 0.06, fz), [(0.03, 0.0), (0.1, 0.03), (0.12, 0.08), (0.1, 0.14), (0.03, 0.16)], 48, True, True)
    o.group("fan_blades")
    for k in range(4):
        fan_blade(o, (fx, fy, fz), 2 * math.pi * k / 4 + 0.3)

    # The sliding soda glass (a strawberry soda) at its start on the counter.
    o.group("sliding_glass")
    soda_glass(o, *GLASS_AT)

    # The ball on the floor, textured so that its rolling shows.
    o.group("ball")
    o.uv_sphere(BALL_AT, BALL_R, 48, 24)

    path = os.path.join(here, "soda-shop.obj")
    with open(path, "w", newline="\n") as f:
        f.write("\n".join(o.lines) + "\n")
    png(os.path.join(here, "wallpaper.png"), wallpaper_texture())
    png(os.path.join(here, "ball.png"), ball_texture())
    png(os.path.join(here, "beadboard.png"), beadboard_texture())
    png(os.path.join(here, "tin.png"), tin_texture())
    print(f"{path}: {o.nv} vertices, {o.nvt} texture coordinates, {o.nt} triangles")
    print(f"pivots: glass {GLASS_AT}, spin seat {SPIN_AT}, fan {FAN_AT}, ball {BALL_AT} r {BALL_R}")


if __name__ == "__main__":
    main()
