#!/usr/bin/env python3
"""Writes studio.obj: an artist's studio lit by the sun through five windows.

Deterministic (fixed seed, fixed number formatting); python3 standard library
only. Units: metres, y up. The room spans x 0..8, y 0..3.5, z 0..6; windows
are cut into the walls z = 0 and x = 0, the sun shines in through them.
Run from anywhere: python3 scenes/studio/generate.py
"""

import math
import os
import random

W, H, D = 8.0, 3.5, 6.0
REVEAL = 0.25  # wall thickness: depth of the window reveals, outwards


class Obj:
    def __init__(self):
        self.lines = []
        self.nv = 0
        self.nt = 0

    def group(self, name):
        self.lines.append(f"o {name}")

    def vert(self, p):
        self.lines.append("v %.4f %.4f %.4f" % tuple(p))
        self.nv += 1
        return self.nv

    def tri(self, a, b, c):
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

    def box(self, lo, hi, n=1):
        """An axis-aligned box facing outwards, each face an n x n grid."""
        x0, y0, z0 = lo
        x1, y1, z1 = hi
        ex, ey, ez = (x1 - x0, 0, 0), (0, y1 - y0, 0), (0, 0, z1 - z0)
        self.grid((x0, y0, z0), ey, ex, n, n)  # z0 side, facing -z
        self.grid((x0, y0, z1), ex, ey, n, n)  # z1, +z
        self.grid((x0, y0, z0), ez, ey, n, n)  # x0, -x
        self.grid((x1, y0, z0), ey, ez, n, n)  # x1, +x
        self.grid((x0, y0, z0), ex, ez, n, n)  # y0, -y
        self.grid((x0, y1, z0), ez, ex, n, n)  # y1, +y

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

    def torus(self, center, big, small, nu, nv):
        cx, cy, cz = center
        idx = [[self.vert((cx + (big + small * math.cos(2 * math.pi * j / nv)) * math.cos(2 * math.pi * i / nu),
                           cy + small * math.sin(2 * math.pi * j / nv),
                           cz + (big + small * math.cos(2 * math.pi * j / nv)) * math.sin(2 * math.pi * i / nu)))
                for j in range(nv)] for i in range(nu)]
        for i in range(nu):
            for j in range(nv):
                i1, j1 = (i + 1) % nu, (j + 1) % nv
                self.quad(idx[i][j], idx[i][j1], idx[i1][j1], idx[i1][j])


def add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def scale(a, s):
    return tuple(x * s for x in a)


def wall_with_holes(o, origin, du, dv, length, height, holes, cell):
    """A wall origin + u du + v dv (unit du, dv; u in [0, length], v in
    [0, height]) facing du x dv, with rectangular holes (u0, v0, u1, v1),
    cut into cells no larger than `cell` so that shared edges line up."""
    us = {0.0, length}
    vs = {0.0, height}
    for u0, v0, u1, v1 in holes:
        us |= {u0, u1}
        vs |= {v0, v1}
    us, vs = refine(sorted(us), cell), refine(sorted(vs), cell)
    idx = {}

    def vid(i, j):
        if (i, j) not in idx:
            idx[(i, j)] = o.vert(add(origin, add(scale(du, us[i]), scale(dv, vs[j]))))
        return idx[(i, j)]

    for i in range(len(us) - 1):
        for j in range(len(vs) - 1):
            mu, mv = (us[i] + us[i + 1]) / 2, (vs[j] + vs[j + 1]) / 2
            if any(u0 < mu < u1 and v0 < mv < v1 for u0, v0, u1, v1 in holes):
                continue
            o.quad(vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1))


def refine(xs, cell):
    out = [xs[0]]
    for a, b in zip(xs, xs[1:]):
        n = max(1, math.ceil((b - a) / cell - 1e-9))
        out += [a + (b - a) * k / n for k in range(1, n + 1)]
    return out


def window(o, origin, du, dv, out, u0, v0, u1, v1):
    """The four reveal faces of a window hole, reaching `out` (outwards)."""
    p = lambda u, v, w=0.0: add(origin, add(scale(du, u), add(scale(dv, v), scale(out, w))))
    o.grid(p(u0, v0), scale(out, REVEAL), scale(du, u1 - u0), 1, 6)   # sill
    o.grid(p(u0, v1), scale(du, u1 - u0), scale(out, REVEAL), 6, 1)   # head
    o.grid(p(u0, v0), scale(dv, v1 - v0), scale(out, REVEAL), 6, 1)   # left jamb
    o.grid(p(u1, v0), scale(out, REVEAL), scale(dv, v1 - v0), 1, 6)   # right jamb


def mullions(o, origin, du, dv, out, u0, v0, u1, v1, w=0.05):
    """A cross of bars in the middle of the reveal."""
    um, vm = (u0 + u1) / 2, (v0 + v1) / 2
    c = REVEAL / 2

    def bar(a0, b0, a1, b1):
        lo = add(origin, add(scale(du, a0), add(scale(dv, b0), scale(out, c - w / 2))))
        hi = add(origin, add(scale(du, a1), add(scale(dv, b1), scale(out, c + w / 2))))
        o.box(tuple(map(min, lo, hi)), tuple(map(max, lo, hi)), 2)

    bar(um - w / 2, v0, um + w / 2, v1)
    bar(u0, vm - w / 2, u1, vm + w / 2)


def table(o, x, z, sx, sz, h=0.75, top=0.04):
    o.box((x - sx / 2, h - top, z - sz / 2), (x + sx / 2, h, z + sz / 2), 12)
    for dx in (-1, 1):
        for dz in (-1, 1):
            o.cylinder((x + dx * (sx / 2 - 0.08), 0, z + dz * (sz / 2 - 0.08)), 0.03, h - top, 32, 6)


def chair(o, x, z, facing):
    """Seat 0.45 high, back on the side away from `facing` (+1/-1 in z)."""
    s = 0.22
    o.box((x - s, 0.42, z - s), (x + s, 0.46, z + s), 6)
    for dx in (-1, 1):
        for dz in (-1, 1):
            o.cylinder((x + dx * (s - 0.03), 0, z + dz * (s - 0.03)), 0.018, 0.42, 24, 4)
    zb = z - facing * (s - 0.02)
    for dx in (-1, 1):
        o.cylinder((x + dx * (s - 0.03), 0.46, zb), 0.018, 0.5, 24, 4)
    for k in range(4):
        y = 0.58 + 0.1 * k
        o.box((x - s, y, zb - 0.01), (x + s, y + 0.05, zb + 0.01), 4)


def easel(o, x, z, angle):
    """Three legs and a ledge holding a canvas, turned by `angle` about y."""
    ca, sa = math.cos(angle), math.sin(angle)
    rot = lambda px, py, pz: (x + ca * px + sa * pz, py, z - sa * px + ca * pz)
    legs = [((-0.35, 0, 0.25), (-0.05, 1.9, 0.0)), ((0.35, 0, 0.25), (0.05, 1.9, 0.0)),
            ((0, 0, -0.45), (0, 1.7, -0.02))]
    for a, b in legs:
        pa, pb = rot(*a), rot(*b)
        # A slender prism along the leg, 8 sides, 10 rings.
        axis = tuple(q - p for p, q in zip(pa, pb))
        ln = math.sqrt(sum(c * c for c in axis))
        t = scale(axis, 1 / ln)
        u = norm(cross(t, (0, 0, 1) if abs(t[2]) < 0.9 else (1, 0, 0)))
        v = cross(t, u)
        rings = []
        for i in range(11):
            c = add(pa, scale(axis, i / 10))
            rings.append([o.vert(add(c, add(scale(u, 0.02 * math.cos(2 * math.pi * k / 8)),
                                            scale(v, 0.02 * math.sin(2 * math.pi * k / 8)))))
                          for k in range(8)])
        for r0, r1 in zip(rings, rings[1:]):
            for k in range(8):
                o.quad(r0[k], r0[(k + 1) % 8], r1[(k + 1) % 8], r1[k])
    ledge = [rot(-0.4, 0.8, 0.2), rot(0.4, 0.8, 0.2), rot(0.4, 0.8, 0.28), rot(-0.4, 0.8, 0.28)]
    o.grid(ledge[0], tuple(q - p for p, q in zip(ledge[0], ledge[3])),
           tuple(q - p for p, q in zip(ledge[0], ledge[1])), 2, 16)


def canvas(o, x, z, angle):
    ca, sa = math.cos(angle), math.sin(angle)
    rot = lambda px, py, pz: (x + ca * px + sa * pz, py, z - sa * px + ca * pz)
    p0 = rot(-0.45, 0.82, 0.21)
    du = tuple(q - p for p, q in zip(p0, rot(0.45, 0.82, 0.21)))
    dv = tuple(q - p for p, q in zip(p0, rot(-0.45, 1.72, 0.12)))
    o.grid(p0, du, dv, 40, 40)


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def norm(a):
    n = math.sqrt(sum(c * c for c in a))
    return tuple(c / n for c in a)


def main():
    rng = random.Random(1996)
    o = Obj()
    o.lines.append("# Artist's studio for the geometric simplification study; see generate.py.")

    # Walls face into the room. Window holes (u0, v0, u1, v1) in wall coordinates.
    south = [(0.8, 0.9, 2.2, 2.9), (3.3, 0.9, 4.7, 2.9), (5.8, 0.9, 7.2, 2.9)]
    west = [(1.2, 0.9, 2.6, 2.9), (3.4, 0.9, 4.8, 2.9)]
    o.group("walls")
    # z = 0 (south): u along +x, faces +z.
    wall_with_holes(o, (0, 0, 0), (1, 0, 0), (0, 1, 0), W, H, south, 0.5)
    # x = 0 (west): u along +z, faces +x: du x dv = z x y = -x, so swap.
    wall_with_holes(o, (0, 0, 0), (0, 1, 0), (0, 0, 1), H, D,
                    [(v0, u0, v1, u1) for u0, v0, u1, v1 in west], 0.5)
    wall_with_holes(o, (W, 0, 0), (0, 0, 1), (0, 1, 0), D, H, [], 0.5)  # x = 8, faces -x
    wall_with_holes(o, (0, 0, D), (0, 1, 0), (1, 0, 0), H, W, [], 0.5)  # z = 6, faces -z
    for u0, v0, u1, v1 in south:
        window(o, (0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, -1), u0, v0, u1, v1)
    for u0, v0, u1, v1 in west:
        window(o, (0, 0, 0), (0, 0, 1), (0, 1, 0), (-1, 0, 0), u0, v0, u1, v1)
    o.group("floor")
    o.grid((0, 0, 0), (0, 0, D), (W, 0, 0), 12, 16)
    o.group("ceiling")
    o.grid((0, H, 0), (W, 0, 0), (0, 0, D), 16, 12)
    o.group("mullions")
    for u0, v0, u1, v1 in south:
        mullions(o, (0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, -1), u0, v0, u1, v1)
    for u0, v0, u1, v1 in west:
        mullions(o, (0, 0, 0), (0, 0, 1), (0, 1, 0), (-1, 0, 0), u0, v0, u1, v1)

    o.group("rug")
    o.grid((2.5, 0.005, 2.0), (0, 0, 2.2), (3.2, 0, 0), 40, 60)
    o.group("tables")
    table(o, 4.1, 3.1, 1.8, 0.9)
    table(o, 6.4, 1.2, 1.4, 0.8)
    o.group("chairs")
    chair(o, 3.6, 2.3, 1)
    chair(o, 4.6, 2.3, 1)
    chair(o, 3.6, 3.9, -1)
    chair(o, 4.6, 3.9, -1)
    chair(o, 6.4, 2.0, -1)

    o.group("shelves")
    sx0, sx1, sz0, sz1 = 0.6, 3.4, 5.62, 5.98
    for k in range(5):
        y = 0.05 + k * 0.5
        o.box((sx0, y, sz0), (sx1, y + 0.03, sz1), 6)
    for xs in (sx0, (sx0 + sx1) / 2, sx1 - 0.03):
        o.box((xs, 0, sz0), (xs + 0.03, 2.1, sz1), 8)
    books = {"books_red": [], "books_green": [], "books_blue": []}
    for k in range(4):
        y = 0.08 + k * 0.5
        x = sx0 + 0.05
        while x < sx1 - 0.1:
            w = 0.02 + 0.03 * rng.random()
            h = 0.2 + 0.18 * rng.random()
            d = 0.18 + 0.12 * rng.random()
            if abs(x + w - (sx0 + sx1) / 2) < 0.05 or rng.random() < 0.08:
                x += w + 0.04
                continue
            books[rng.choice(sorted(books))].append(((x, y, sz1 - 0.01 - d), (x + w, y + h, sz1 - 0.01)))
            x += w + 0.004
    for name in sorted(books):
        o.group(name)
        for lo, hi in books[name]:
            o.box(lo, hi, 2)

    o.group("easels")
    easel(o, 1.3, 2.3, 0.6)
    easel(o, 7.0, 4.0, -2.2)
    o.group("canvases")
    canvas(o, 1.3, 2.3, 0.6)
    canvas(o, 7.0, 4.0, -2.2)

    o.group("pedestal")
    o.box((5.0, 0, 4.9), (5.6, 0.9, 5.5), 8)
    o.group("sculpture")
    o.sphere((5.3, 1.2, 5.2), 0.3, 96, 48)
    o.group("torus")
    o.torus((4.1, 0.86, 3.1), 0.16, 0.07, 64, 32)
    o.group("vases")
    vase = [(0.05 + 0.06 * math.sin(math.pi * i / 24) ** 2 + 0.02 * i / 24, 0.32 * i / 24) for i in range(25)]
    for cx, cy, cz in ((6.1, 0.75, 1.1), (6.7, 0.75, 1.3), (1.0, 2.08, 5.8), (2.9, 1.58, 5.8), (7.6, 0, 0.4)):
        o.revolve((cx, cy, cz), vase, 36, True, False)
    o.group("mirror")
    o.grid((W - 0.02, 0.7, 4.0), (0, 1.5, 0), (0, 0, 1.4), 1, 1)

    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "studio.obj")
    with open(path, "w", newline="\n") as f:
        f.write("\n".join(o.lines) + "\n")
    print(f"{path}: {o.nv} vertices, {o.nt} triangles")


if __name__ == "__main__":
    main()
