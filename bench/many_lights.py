#!/usr/bin/env python3
"""Time to unit variance of the light samplers on a many-lights scene.

Renders SCENE with each --light-sampler in turn (uniform, power, bvh,
cachepoints, uniform, ...: interleaved, so that the shared machine's load falls on all of
them alike), reads each render's relMSE against REFERENCE (`theia diff`), its
wall seconds from the log (total: cache-point build included; render: the
iterations alone) and the process's CPU seconds and peak RSS (os.wait4).
relMSE of an unbiased estimator is its variance over the squared mean, so
relMSE x seconds is the time to unit variance (seeds/002 Tables 1-4): lower is
better, and the ratio between samplers does not depend on the spp.
Each sampler's build seconds (its log's light_sampler section) and peak RSS
are reported beside it.

  bench/many_lights.py --theia build/theia --scene scenes/many-lights-city/scene.pbrt \
      --reference tests/data/many-lights-city.exr --spp 64 --runs 3

--city100k renders a larger city instead, generated on the fly into a
temporary folder by scenes/many-lights-city/make_scene.py (26 x 26 lots,
45,000 windows and 5,000 lamps: 50,000 quads, 100,000 emitting triangles,
5 MB of text, so not committed); it has no pbrt-v4 reference, so the script
first renders one with --reference-sampler at --reference-spp (seed 1000,
independent of the runs' seeds 0..runs-1; `--reference render` does the same
for any scene), whose own relMSE adds the same small constant to every
sampler's:

  bench/many_lights.py --theia build/theia --city100k --spp 32 --runs 3

--mesh100k does the same with the same city's windows and lamps as one
emissive mesh of 100,000 triangles and one radiance (make_scene.py
--one-mesh-light): one light that pbrt-v4 and theia's many-lights samplers
sample per triangle.

--pbrt PATH also renders the scene with pbrt-v4 (its BVH light sampler: the
scene's Integrator must be pbrt-v4's path or volpath with "lightsampler" "bvh"
or unset, which is pbrt-v4's default), after theia's samplers in every run
(uniform, ..., cachepoints, pbrt-v4, uniform, ...), at --pbrt-spp (default
--spp) with the run's seed, and reports it beside them with the same figures:
relMSE against the same reference, CPU seconds and peak RSS from os.wait4.
pbrt-v4 writes no log, so its wall seconds are its whole process's (scene
load and builds included, like theia's log total).  pbrt-v4 renders
spectrally and theia in RGB, so every row also shows its image mean over the
reference's (R G B), and the summary the ratio of pbrt-v4's mean to that of
theia's best sampler (the lowest relMSE):

  bench/many_lights.py --theia build/theia --pbrt /path/to/pbrt --spp 64 --runs 3
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile

from compare_pbrt import pbrt_cmd, run_measured

PBRT_ROW = "pbrt-v4"
# pbrt-v4's integrators that read "lightsampler" (src/pbrt/cpu/integrators.cpp); both default to "bvh".
PBRT_LIGHT_SAMPLER_INTEGRATORS = ("path", "volpath")


def diff_figures(out):
    """relMSE and channel_mean_ratio (a list) from `theia diff` output."""
    figures = {}
    for line in out.splitlines():
        words = line.split()
        if len(words) >= 2 and words[0] == "relMSE":
            figures["rel_mse"] = float(words[1])
        elif len(words) >= 2 and words[0] == "channel_mean_ratio":
            figures["mean_ratio"] = [float(w) for w in words[1:]]
    if set(figures) != {"rel_mse", "mean_ratio"}:
        sys.exit(f"no relMSE or channel_mean_ratio in `theia diff` output (theia older than this script?): {out}")
    return figures


def compare(theia, image, reference):
    out = subprocess.run([theia, "diff", image, reference], capture_output=True, text=True, check=True).stdout
    return diff_figures(out)


def pbrt_integrator(text):
    """(integrator, light sampler) pbrt-v4 renders this scene text with: its Integrator directive
    (before WorldBegin) and "string lightsampler", else pbrt-v4's defaults, volpath and bvh.
    Comments are dropped first; an Include before WorldBegin is not followed."""
    head = re.split(r"^\s*WorldBegin\b", re.sub(r"#[^\n]*", "", text), maxsplit=1, flags=re.M)[0]
    m = re.search(r'\bIntegrator\s+"(\w+)"(.*?)(?=\b[A-Z][A-Za-z]+\s|\Z)', head, flags=re.S)
    if not m:
        return "volpath", "bvh"
    ls = re.search(r'"string\s+lightsampler"\s*\[?\s*"(\w+)"', m.group(2))
    return m.group(1), ls.group(1) if ls else "bvh"


def check_pbrt_scene(scene):
    """Exits unless pbrt-v4 renders the scene with its BVH light sampler (the row is labelled so)."""
    with open(scene, encoding="utf-8", errors="replace") as f:
        integrator, sampler = pbrt_integrator(f.read())
    if integrator not in PBRT_LIGHT_SAMPLER_INTEGRATORS or sampler != "bvh":
        sys.exit(f'{scene}: pbrt-v4 would render it with Integrator "{integrator}" and light sampler "{sampler}"; '
                 f'--pbrt compares its BVH light sampler: use {" or ".join(PBRT_LIGHT_SAMPLER_INTEGRATORS)} with '
                 '"string lightsampler" "bvh" (or unset)')


# The generated scenes (5 MB of text each, so not committed): make_scene.py's arguments.
CITY100K = ["--lots", "26", "--windows", "45000", "--lamps", "5000"]
VARIANTS = {"city100k": CITY100K, "mesh100k": CITY100K + ["--one-mesh-light"]}


def make_variant(tmp, name):
    """Writes the generated scene `name` (a key of VARIANTS) into tmp; its path."""
    here = os.path.dirname(os.path.abspath(__file__))
    scene = os.path.join(tmp, name + ".pbrt")
    subprocess.run([sys.executable, os.path.join(here, "..", "scenes", "many-lights-city", "make_scene.py"),
                    *VARIANTS[name], "--output", scene], check=True, stdout=subprocess.DEVNULL)
    return scene


def render(args, scene, sampler, spp, seed, exr):
    """(log, CPU seconds, peak MiB) of one render."""
    r = run_measured([args.theia, "render", scene, "--spp", str(spp), "--seed", str(seed),
                      "--light-sampler", sampler, "--no-guiding", "-o", exr, "-q"], exr + ".out")
    with open(exr[:-len(".exr")] + ".json") as f:
        return json.load(f), r.cpu_s, r.peak_mib


def render_pbrt(args, scene, seed, exr):
    """compare_pbrt.Run (CPU seconds, peak MiB, wall seconds) of one pbrt-v4 render; its thread count
    is its default (every core), as theia's is."""
    return run_measured(pbrt_cmd(args.pbrt, scene, args.pbrt_spp, exr, seed), exr + ".out")


def median_ratio(rows, name):
    """Per-channel median over runs of one row name's image mean over the reference's."""
    ratios = [x["mean_ratio"] for x in rows if x["sampler"] == name]
    return [statistics.median(r[c] for r in ratios) for c in range(len(ratios[0]))]


def summary_table(rows, names):
    """Markdown lines: per row name, medians over its runs; TUV = relMSE x seconds (wall: the log's
    total, or the process's for pbrt-v4; CPU: the process's), the ratio the first name's over this one's."""
    med = lambda s, k: statistics.median(x[k] for x in rows if x["sampler"] == s)
    base = {k: med(names[0], "rel_mse") * med(names[0], k) for k in ("total_seconds", "cpu_seconds")}
    out = ["| sampler | relMSE | wall s (build) | CPU s | TUV wall | TUV CPU | peak MiB | mean / reference R G B |",
           "|---|---|---|---|---|---|---|---|"]
    for s in names:
        tw, tc = med(s, "rel_mse") * med(s, "total_seconds"), med(s, "rel_mse") * med(s, "cpu_seconds")
        build = "-" if s == PBRT_ROW else f"{med(s, 'build_seconds'):.1f}"
        ratio = " ".join(f"{v:.3f}" for v in median_ratio(rows, s))
        out.append(f"| {s} | {med(s, 'rel_mse'):.4f} | {med(s, 'total_seconds'):.1f} ({build}) "
                   f"| {med(s, 'cpu_seconds'):.1f} | {tw:.3f} ({base['total_seconds'] / tw:.1f}x) "
                   f"| {tc:.3f} ({base['cpu_seconds'] / tc:.1f}x) "
                   f"| {max(x['peak_mib'] for x in rows if x['sampler'] == s):.0f} | {ratio} |")
    return out


def pbrt_over_theia(rows, samplers):
    """(theia sampler, per-channel ratio): pbrt-v4's image mean over that of theia's sampler with the
    lowest median relMSE (the least noisy mean), both medians over runs against the same reference."""
    best = min(samplers, key=lambda s: statistics.median(x["rel_mse"] for x in rows if x["sampler"] == s))
    return best, [p / t for p, t in zip(median_ratio(rows, PBRT_ROW), median_ratio(rows, best))]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--theia", default="build/theia")
    ap.add_argument("--scene", default="scenes/many-lights-city/scene.pbrt")
    ap.add_argument("--reference", default="tests/data/many-lights-city.exr",
                    help="the converged image, or 'render' to render one as for --city100k")
    ap.add_argument("--samplers", default="uniform,power,bvh,cachepoints")
    variant = ap.add_mutually_exclusive_group()
    variant.add_argument("--city100k", action="store_true", help="generate and render the 100k-emitter city")
    variant.add_argument("--mesh100k", action="store_true",
                         help="generate and render the city with one emissive mesh of 100k triangles")
    ap.add_argument("--reference-sampler", default="cachepoints")
    ap.add_argument("--reference-spp", type=int, default=1024)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--json", help="write every measurement here")
    ap.add_argument("--pbrt", help="pbrt-v4 binary: also render with its BVH light sampler, after theia's samplers")
    ap.add_argument("--pbrt-spp", type=int, help="pbrt-v4's samples per pixel (default: --spp)")
    args = ap.parse_args()
    samplers = args.samplers.split(",")
    args.pbrt_spp = args.pbrt_spp or args.spp
    if args.pbrt_spp < 1 or args.spp < 1:
        ap.error("--spp and --pbrt-spp must be at least 1")
    rows = []
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        generated = "city100k" if args.city100k else "mesh100k" if args.mesh100k else None
        scene, reference = (make_variant(tmp, generated) if generated else args.scene), args.reference
        if args.pbrt:
            check_pbrt_scene(scene)
        if generated or reference == "render":
            reference = os.path.join(tmp, "reference.exr")
            log, cpu, _ = render(args, scene, args.reference_sampler, args.reference_spp, 1000, reference)
            print(f"reference: {args.reference_sampler} {args.reference_spp} spp, {log['time']['total']:.1f} s wall, "
                  f"{cpu:.1f} CPU-s", flush=True)
        for r in range(args.runs):
            for s in samplers:
                exr = os.path.join(tmp, f"{s}-{r}.exr")
                log, cpu, peak = render(args, scene, s, args.spp, r, exr)
                rows.append({"sampler": s, "run": r, "spp": args.spp, **compare(args.theia, exr, reference),
                             "total_seconds": log["time"]["total"], "render_seconds": log["time"]["render"],
                             "cpu_seconds": cpu, "peak_mib": peak,
                             "build_seconds": log.get("light_sampler", {}).get("build_seconds", 0.0)})
                print(json.dumps(rows[-1]), flush=True)
            if args.pbrt:
                exr = os.path.join(tmp, f"pbrt-{r}.exr")
                p = render_pbrt(args, scene, r, exr)
                rows.append({"sampler": PBRT_ROW, "run": r, "spp": args.pbrt_spp, **compare(args.theia, exr, reference),
                             "total_seconds": p.wall_s, "cpu_seconds": p.cpu_s, "peak_mib": p.peak_mib})
                print(json.dumps(rows[-1]), flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    names = samplers + ([PBRT_ROW] if args.pbrt else [])
    spp = f"{args.spp} spp" + (f" (pbrt-v4: {args.pbrt_spp})" if args.pbrt and args.pbrt_spp != args.spp else "")
    print(f"\n{spp}, {args.runs} interleaved runs, medians; TUV = relMSE x seconds "
          f"(ratio: {names[0]}'s over this one's); load average {load_before:.1f} before, "
          f"{os.getloadavg()[0]:.1f} after\n")
    print("\n".join(summary_table(rows, names)))
    if args.pbrt:
        best, ratio = pbrt_over_theia(rows, samplers)
        print(f"\npbrt-v4's image mean over theia's ({best}, the lowest relMSE), R G B: "
              + " ".join(f"{v:.4f}" for v in ratio))


if __name__ == "__main__":
    main()
