#!/usr/bin/python3
"""Writes the material sweep's textures and hair curves (run from anywhere; needs numpy, PIL).

textures/:

bumps.png      64x64 16-bit grey height field, 0.5 + 0.25 (sin 4 pi x + sin 4 pi y) over the
               tile (two periods each way): the "displacement" of bump and the "amount" of
               mix-textured.
normals.png    64x64 8-bit RGB tangent-space normal map of the same pattern (slopes up to 0.5),
               encoded as (n + 1) / 2 and read as linear.
checker.png    128x128 8-bit sRGB: 8-texel checks in orange and blue with a one-texel white
               grid line, the reflectance of the texture-filter scenes (fine detail that a
               grazing footprint must average).
hair/curves.pbrt  240 flat cubic Bezier hairs (width 0.015) arching from the floor over a dome of
               radius 0.7 where the other scenes have the sphere, from a fixed seed.
"""
import os

import numpy as np
from PIL import Image

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "textures")
HAIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "hair", "curves.pbrt")


def height(n):
    x = (np.arange(n) + 0.5) / n
    return 0.5 + 0.25 * (np.sin(4 * np.pi * x)[None, :] + np.sin(4 * np.pi * x)[:, None])


def write_bumps(n=64):
    h = height(n)
    Image.fromarray(np.round(h * 65535).astype(np.uint16)).save(os.path.join(HERE, "bumps.png"))


def write_normals(n=64):
    x = (np.arange(n) + 0.5) / n
    dh = 0.5 * np.cos(4 * np.pi * x)
    dhdx = np.broadcast_to(dh[None, :], (n, n))
    dhdy = np.broadcast_to(dh[:, None], (n, n))
    # Image rows run down while v runs up (v = 1 - row / n), hence the sign of y.
    nrm = np.stack([-dhdx, dhdy, np.ones((n, n))], axis=-1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    Image.fromarray(np.round((nrm + 1) / 2 * 255).astype(np.uint8), "RGB").save(os.path.join(HERE, "normals.png"))


def write_checker(n=128, cell=8):
    i = np.arange(n)
    odd = ((i[None, :] // cell + i[:, None] // cell) % 2).astype(bool)
    img = np.where(odd[..., None], np.array([230, 120, 40]), np.array([40, 110, 210]))
    line = (i % cell == 0)
    img[line, :] = 250
    img[:, line] = 250
    Image.fromarray(img.astype(np.uint8), "RGB").save(os.path.join(HERE, "checker.png"))


def write_hair(count=240, width=0.015, seed=5):
    rng = np.random.default_rng(seed)
    lines = ["# Written by make_assets.py: %d hairs arching over the sphere's place." % count]
    for _ in range(count):
        # A meridian-like arc of the dome x^2 + y'^2 + z^2 = r^2 (y' = y + 0.7) between two floor
        # points, tilted by a random azimuth, its height and radius jittered.
        phi = rng.uniform(0, np.pi)
        r = 0.7 * rng.uniform(0.8, 1.05)
        d = np.array([np.cos(phi), 0, np.sin(phi)])
        off = rng.uniform(-0.5, 0.5) * r * np.array([-np.sin(phi), 0, np.cos(phi)])
        h = r * rng.uniform(0.7, 1.2)
        a, b = off - r * d, off + r * d
        # cubic Bezier from a up to about h and down to b (control points 4/3 h for a peak of h)
        p = [a, a + np.array([0, 4 / 3 * h, 0]), b + np.array([0, 4 / 3 * h, 0]), b]
        y0 = -0.7
        pts = " ".join("%.5f %.5f %.5f" % (q[0], q[1] + y0, q[2]) for q in p)
        lines.append('Shape "curve" "string type" ["flat"] "point3 P" [%s] "float width" [%g]' % (pts, width))
    with open(HAIR, "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    write_hair()
    write_bumps()
    write_normals()
    write_checker()
