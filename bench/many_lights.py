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
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile


def run(cmd):
    """(exit code, CPU seconds, peak RSS MiB) of one process."""
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed: {proc.stderr.read().decode()}")
    return usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0


def rel_mse(theia, image, reference):
    out = subprocess.run([theia, "diff", image, reference], capture_output=True, text=True, check=True).stdout
    for line in out.splitlines():
        key, value = line.split()[:2]
        if key == "relMSE":
            return float(value)
    sys.exit(f"no relMSE in `theia diff` output: {out}")


def make_city100k(tmp):
    here = os.path.dirname(os.path.abspath(__file__))
    scene = os.path.join(tmp, "city100k.pbrt")
    subprocess.run([sys.executable, os.path.join(here, "..", "scenes", "many-lights-city", "make_scene.py"),
                    "--lots", "26", "--windows", "45000", "--lamps", "5000", "--output", scene],
                   check=True, stdout=subprocess.DEVNULL)
    return scene


def render(args, scene, sampler, spp, seed, exr):
    """(log, CPU seconds, peak MiB) of one render."""
    cpu, peak = run([args.theia, "render", scene, "--spp", str(spp), "--seed", str(seed),
                     "--light-sampler", sampler, "-o", exr, "-q"])
    with open(exr[:-len(".exr")] + ".json") as f:
        return json.load(f), cpu, peak


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--theia", default="build/theia")
    ap.add_argument("--scene", default="scenes/many-lights-city/scene.pbrt")
    ap.add_argument("--reference", default="tests/data/many-lights-city.exr",
                    help="the converged image, or 'render' to render one as for --city100k")
    ap.add_argument("--samplers", default="uniform,power,bvh,cachepoints")
    ap.add_argument("--city100k", action="store_true", help="generate and render the 100k-emitter city")
    ap.add_argument("--reference-sampler", default="cachepoints")
    ap.add_argument("--reference-spp", type=int, default=1024)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--json", help="write every measurement here")
    args = ap.parse_args()
    samplers = args.samplers.split(",")
    rows = []
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        scene, reference = (make_city100k(tmp) if args.city100k else args.scene), args.reference
        if args.city100k or reference == "render":
            reference = os.path.join(tmp, "reference.exr")
            log, cpu, _ = render(args, scene, args.reference_sampler, args.reference_spp, 1000, reference)
            print(f"reference: {args.reference_sampler} {args.reference_spp} spp, {log['time']['total']:.1f} s wall, "
                  f"{cpu:.1f} CPU-s", flush=True)
        for r in range(args.runs):
            for s in samplers:
                exr = os.path.join(tmp, f"{s}-{r}.exr")
                log, cpu, peak = render(args, scene, s, args.spp, r, exr)
                e = rel_mse(args.theia, exr, reference)
                rows.append({"sampler": s, "run": r, "rel_mse": e, "total_seconds": log["time"]["total"],
                             "render_seconds": log["time"]["render"], "cpu_seconds": cpu, "peak_mib": peak,
                             "build_seconds": log.get("light_sampler", {}).get("build_seconds", 0.0)})
                print(json.dumps(rows[-1]), flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    med = lambda s, k: statistics.median(x[k] for x in rows if x["sampler"] == s)
    base = {k: med(samplers[0], "rel_mse") * med(samplers[0], k) for k in ("total_seconds", "cpu_seconds")}
    print(f"\n{args.spp} spp, {args.runs} interleaved runs, medians; TUV = relMSE x seconds "
          f"(ratio: {samplers[0]}'s over this one's); load average {load_before:.1f} before, "
          f"{os.getloadavg()[0]:.1f} after\n")
    print("| sampler | relMSE | wall s (build) | CPU s | TUV wall | TUV CPU | peak MiB |")
    print("|---|---|---|---|---|---|---|")
    for s in samplers:
        tw, tc = med(s, "rel_mse") * med(s, "total_seconds"), med(s, "rel_mse") * med(s, "cpu_seconds")
        print(f"| {s} | {med(s, 'rel_mse'):.4f} | {med(s, 'total_seconds'):.1f} ({med(s, 'build_seconds'):.1f}) "
              f"| {med(s, 'cpu_seconds'):.1f} | {tw:.3f} ({base['total_seconds'] / tw:.1f}x) "
              f"| {tc:.3f} ({base['cpu_seconds'] / tc:.1f}x) | {max(x['peak_mib'] for x in rows if x['sampler'] == s):.0f} |")


if __name__ == "__main__":
    main()
