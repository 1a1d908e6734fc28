#!/usr/bin/env python3
"""Time to unit variance of the light samplers on a many-lights scene.

Renders SCENE with each --light-sampler in turn (uniform, power, cachepoints,
uniform, ...: interleaved, so that the shared machine's load falls on all of
them alike), reads each render's relMSE against REFERENCE (`theia diff`), its
wall seconds from the log (total: cache-point build included; render: the
iterations alone) and the process's CPU seconds and peak RSS (os.wait4).
relMSE of an unbiased estimator is its variance over the squared mean, so
relMSE x seconds is the time to unit variance (seeds/002 Tables 1-4): lower is
better, and the ratio between samplers does not depend on the spp.

  bench/many_lights.py --theia build/theia --scene scenes/many-lights-city/scene.pbrt \
      --reference tests/data/many-lights-city.exr --spp 64 --runs 3
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


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--theia", default="build/theia")
    ap.add_argument("--scene", default="scenes/many-lights-city/scene.pbrt")
    ap.add_argument("--reference", default="tests/data/many-lights-city.exr")
    ap.add_argument("--samplers", default="uniform,power,cachepoints")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--json", help="write every measurement here")
    args = ap.parse_args()
    samplers = args.samplers.split(",")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.runs):
            for s in samplers:
                exr = os.path.join(tmp, f"{s}-{r}.exr")
                cpu, peak = run([args.theia, "render", args.scene, "--spp", str(args.spp), "--seed", str(r),
                                 "--light-sampler", s, "-o", exr, "-q"])
                with open(os.path.join(tmp, f"{s}-{r}.json")) as f:
                    log = json.load(f)
                e = rel_mse(args.theia, exr, args.reference)
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
          f"(ratio: {samplers[0]}'s over this one's)\n")
    print("| sampler | relMSE | wall s (build) | CPU s | TUV wall | TUV CPU | peak MiB |")
    print("|---|---|---|---|---|---|---|")
    for s in samplers:
        tw, tc = med(s, "rel_mse") * med(s, "total_seconds"), med(s, "rel_mse") * med(s, "cpu_seconds")
        print(f"| {s} | {med(s, 'rel_mse'):.4f} | {med(s, 'total_seconds'):.1f} ({med(s, 'build_seconds'):.1f}) "
              f"| {med(s, 'cpu_seconds'):.1f} | {tw:.3f} ({base['total_seconds'] / tw:.1f}x) "
              f"| {tc:.3f} ({base['cpu_seconds'] / tc:.1f}x) | {max(x['peak_mib'] for x in rows if x['sampler'] == s):.0f} |")


if __name__ == "__main__":
    main()
