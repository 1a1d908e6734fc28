#!/usr/bin/env python3
"""Writes an unoccluded many-lights scene for bench/many_lights.py: a grey
floor under an N x N grid of small downward-facing emissive quads (2 N^2
emitting triangles, radiances over three decades, deterministic), a dim sky,
nothing in between; 160 x 90, the camera looking down the floor.  Every light
sees every floor point, so occlusion cannot help a sampler here: it measures
what a sampler's selection costs and gains from the light count alone.

  bench/make_street.py --n 16 --output /tmp/street16.pbrt
"""
import argparse
import random


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, required=True, help="lights per side")
    ap.add_argument("--output", required=True)
    args = ap.parse_args()
    rng = random.Random(1414)
    out = ['Integrator "volpath" "integer maxdepth" [ 5 ]\n',
           'Film "rgb" "integer xresolution" [ 160 ] "integer yresolution" [ 90 ]\n',
           'LookAt 0 6 -24  0 0 0  0 1 0\nCamera "perspective" "float fov" [ 40 ]\nWorldBegin\n',
           'LightSource "infinite" "rgb L" [ 0.01 0.01 0.02 ]\n',
           'Material "diffuse" "rgb reflectance" [ 0.5 0.5 0.5 ]\n',
           'Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ] '
           '"point3 P" [ -20 0 -20  20 0 -20  20 0 20  -20 0 20 ]\n']
    half, size = 0.1, 30.0
    for i in range(args.n):
        for j in range(args.n):
            x = -size / 2 + size * (i + 0.5) / args.n
            z = -size / 2 + size * (j + 0.5) / args.n
            y = rng.uniform(2.0, 5.0)
            L = 0.3 * 10 ** rng.uniform(0.0, 3.0)
            # Winding (p1 - p0) x (p2 - p0) = -y: facing the floor.
            P = f"{x - half} {y} {z - half}  {x + half} {y} {z - half}  {x + half} {y} {z + half}  {x - half} {y} {z + half}"
            out.append(f'AttributeBegin\nAreaLightSource "diffuse" "rgb L" [ {L:.4g} {L:.4g} {L:.4g} ]\n'
                       f'Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ] "point3 P" [ {P} ]\nAttributeEnd\n')
    with open(args.output, "w") as f:
        f.write("".join(out))


if __name__ == "__main__":
    main()
