#!/usr/bin/python3
"""theia against pbrt-v4: CPU seconds per sample and peak memory at equal spp.

Each scene is rendered by both programs in turn (theia, pbrt, theia, pbrt, ...)
so that load on the shared machine falls on both alike.  A run's cost is the
user + system CPU time and the peak resident set of its process, read from
os.wait4's rusage: start-up, scene loading and BVH build count, as they do for
whoever waits for the image.

    compare_pbrt.py --theia build/theia --pbrt /path/to/pbrt --spp 64 --runs 3 [SCENE ...]
    compare_pbrt.py --theia build/theia --base OLD/theia --pbrt /path/to/pbrt --spp 64 --runs 3
    compare_pbrt.py --theia build/theia --threads 1,2 --spp 16 --runs 3 [SCENE ...]

--base adds an earlier theia build to the same rotation (base, theia, pbrt,
base, ...): the machine's speed drifts by the hour, and a change is only
measured against a build run in the same minutes.  The second form renders
with theia alone at each thread count and reports wall-time scaling.  Standard library only (Debian's /usr/bin/python3)."""
import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VALIDATION_SCENES = ["cornell-box", "living-room", "material-testball", "veach-ajar", "veach-mis"]


def film_pixels(scene_path):
    """Pixels of the scene's Film (pbrt-v4's default 1280x720 where unset)."""
    text = open(scene_path, encoding="utf-8", errors="replace").read()
    def res(axis, default):
        m = re.search(r'"integer\s+' + axis + r'resolution"\s*\[?\s*(\d+)', text)
        return int(m.group(1)) if m else default
    return res("x", 1280) * res("y", 720)


class Run:
    """One finished process: CPU seconds (user + sys), peak RSS, wall seconds."""
    def __init__(self, cpu_s, peak_mib, wall_s):
        self.cpu_s, self.peak_mib, self.wall_s = cpu_s, peak_mib, wall_s


def run_measured(cmd, log_path):
    with open(log_path, "wb") as log:
        t0 = time.monotonic()
        p = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT)
        _, status, ru = os.wait4(p.pid, 0)
        wall = time.monotonic() - t0
    p.returncode = os.waitstatus_to_exitcode(status)  # reaped here, not by Popen
    if p.returncode != 0:
        tail = open(log_path, errors="replace").read()[-2000:]
        sys.exit(f"{' '.join(cmd)}\nexited {p.returncode}; its output ends:\n{tail}")
    return Run(ru.ru_utime + ru.ru_stime, ru.ru_maxrss / 1024.0, wall)  # ru_maxrss: KiB on Linux


def theia_cmd(binary, scene, spp, out, threads=None):
    # Unguided, as pbrt-v4's volpath is (theia's default, --guiding-auto, would
    # probe guiding above its training budget of spp).
    cmd = [binary, "render", scene, "--spp", str(spp), "--no-guiding", "-q", "-o", out]
    return cmd + ["--threads", str(threads)] if threads else cmd


def pbrt_cmd(binary, scene, spp, out, seed=None):
    seed = ["--seed", str(seed)] if seed is not None else []
    return [binary, "--spp", str(spp)] + seed + ["--outfile", out, scene]


class Summary:
    """min and median over runs of one renderer on one scene."""
    def __init__(self, runs, samples):
        cpu = [r.cpu_s for r in runs]
        self.cpu_min, self.cpu_med = min(cpu), statistics.median(cpu)
        self.us_per_sample_min = self.cpu_min / samples * 1e6
        self.us_per_sample_med = self.cpu_med / samples * 1e6
        self.peak_mib = max(r.peak_mib for r in runs)
        self.wall_med = statistics.median(r.wall_s for r in runs)


def speed_ratio(pbrt, theia):
    """theia's samples per CPU second over pbrt-v4's, i.e. pbrt CPU-s / theia CPU-s
    at equal samples (> 1: theia does more samples per CPU second)."""
    return pbrt.cpu_med / theia.cpu_med, pbrt.cpu_min / theia.cpu_min


def paired_ratio(num_runs, den_runs):
    """Median over rounds k of num[k] / den[k] CPU-s: runs of one round share the
    machine's minutes, so the ratio holds when the machine's speed drifts."""
    return statistics.median(n.cpu_s / d.cpu_s for n, d in zip(num_runs, den_runs))


def round_order(builds, k):
    """The theia builds of round k: reversed every other round, so that neither
    of two builds always runs first (a cold page cache, a clock that ramps)."""
    return list(reversed(builds)) if k % 2 == 0 else list(builds)


def comparison_table(rows):
    """rows: (scene, pixels, spp, theia Summary, pbrt Summary[, base Summary]) -> markdown lines.
    With a base, two more columns: pbrt-v4 against the base, and the base's CPU-s
    over theia's (> 1: theia is faster than the base)."""
    with_base = any(len(r) > 5 for r in rows)
    extra = " pbrt CPU-s / base CPU-s med | base CPU-s / theia CPU-s med |" if with_base else ""
    out = ["| scene | pixels x spp | theia CPU-us/sample min / med | pbrt-v4 CPU-us/sample min / med "
           "| pbrt CPU-s / theia CPU-s med (min) | theia peak MiB | pbrt-v4 peak MiB |" + extra,
           "|---|---|---|---|---|---|---|" + ("---|---|" if with_base else "")]
    for scene, pixels, spp, t, p, *base in rows:
        med, mn = speed_ratio(p, t)
        line = (f"| {scene} | {pixels} x {spp} | {t.us_per_sample_min:.3f} / {t.us_per_sample_med:.3f} "
                f"| {p.us_per_sample_min:.3f} / {p.us_per_sample_med:.3f} | {med:.2f} ({mn:.2f}) "
                f"| {t.peak_mib:.0f} | {p.peak_mib:.0f} |")
        if base:
            line += f" {p.cpu_med / base[0].cpu_med:.2f} | {base[0].cpu_med / t.cpu_med:.3f} |"
        out.append(line)
    return out


def scaling_table(rows, threads):
    """rows: (scene, {threads: Summary}) -> markdown lines; speed-up against the first count."""
    base = threads[0]
    head = "| scene | " + " | ".join(f"{n} thr wall s (med)" for n in threads)
    head += " | " + " | ".join(f"speed-up {base}->{n}" for n in threads[1:])
    head += " | " + " | ".join(f"{n} thr CPU-s (med)" for n in threads) + " |"
    out = [head, "|" + "---|" * (1 + 3 * len(threads) - 1)]
    for scene, by_n in rows:
        cells = [f"{by_n[n].wall_med:.2f}" for n in threads]
        cells += [f"{by_n[base].wall_med / by_n[n].wall_med:.2f}x" for n in threads[1:]]
        cells += [f"{by_n[n].cpu_med:.2f}" for n in threads]
        out.append(f"| {scene} | " + " | ".join(cells) + " |")
    return out


def load_note(before):
    """The 1-minute load average before and after: wall times on a shared machine need it."""
    return f"load average {before:.1f} before, {os.getloadavg()[0]:.1f} after"


def resolve_scenes(names):
    paths = []
    for s in names or VALIDATION_SCENES:
        p = s if s.endswith(".pbrt") else os.path.join(REPO, "scenes", s, "scene.pbrt")
        if not os.path.isfile(p):
            sys.exit(f"no scene file {p}")
        paths.append(p)
    return paths


def scene_name(path):
    return os.path.basename(os.path.dirname(path)) if os.path.basename(path) == "scene.pbrt" else path


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*", help="scene names under scenes/ or .pbrt paths (default: the validation scenes)")
    ap.add_argument("--theia", required=True)
    ap.add_argument("--pbrt", help="pbrt-v4 binary (required unless --threads)")
    ap.add_argument("--base", help="an earlier theia binary, rendered in the same rotation")
    ap.add_argument("--spp", type=int, required=True)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--threads", help="comma-separated theia thread counts: report scaling instead of comparing")
    ap.add_argument("--keep", help="directory for images and logs (default: a temporary one)")
    a = ap.parse_args()
    if not a.threads and not a.pbrt:
        ap.error("--pbrt is required unless --threads is given")
    scenes = resolve_scenes(a.scenes)
    work = a.keep or tempfile.mkdtemp(prefix="theia-compare-")
    os.makedirs(work, exist_ok=True)

    load_before = os.getloadavg()[0]
    if a.threads:
        threads = [int(n) for n in a.threads.split(",")]
        rows = []
        for scene in scenes:
            name = scene_name(scene)
            runs = {n: [] for n in threads}
            for k in range(a.runs):
                for n in threads:  # interleaved: 1 2 1 2 ...
                    out = os.path.join(work, f"{name}-t{n}-{k}.exr")
                    runs[n].append(run_measured(theia_cmd(a.theia, scene, a.spp, out, n), out + ".out"))
            samples = a.spp * film_pixels(scene)
            rows.append((name, {n: Summary(r, samples) for n, r in runs.items()}))
            print(f"{name}: done", file=sys.stderr)
        print(f"theia thread scaling, {a.spp} spp, {a.runs} interleaved runs each; {load_note(load_before)}")
        print("\n".join(scaling_table(rows, threads)))
        return

    rows, paired_lines = [], []
    for scene in scenes:
        name = scene_name(scene)
        theia_runs, pbrt_runs, base_runs = [], [], []
        for k in range(a.runs):  # interleaved: [base] theia pbrt theia [base] pbrt ...
            builds = [("theia", a.theia, theia_runs)] + ([("base", a.base, base_runs)] if a.base else [])
            for tag, binary, runs in round_order(builds, k):
                out = os.path.join(work, f"{name}-{tag}-{k}.exr")
                runs.append(run_measured(theia_cmd(binary, scene, a.spp, out), out + ".out"))
            out = os.path.join(work, f"{name}-pbrt-{k}.exr")
            pbrt_runs.append(run_measured(pbrt_cmd(a.pbrt, scene, a.spp, out), out + ".out"))
        pixels = film_pixels(scene)
        samples = a.spp * pixels
        row = (name, pixels, a.spp, Summary(theia_runs, samples), Summary(pbrt_runs, samples))
        rows.append(row + ((Summary(base_runs, samples),) if a.base else ()))
        paired = f"paired pbrt / theia {paired_ratio(pbrt_runs, theia_runs):.3f}"
        if a.base:
            paired += (f", pbrt / base {paired_ratio(pbrt_runs, base_runs):.3f}, "
                       f"base / theia {paired_ratio(base_runs, theia_runs):.3f}")
        paired_lines.append(f"- {name}: {paired}")
        print(f"{name}: done", file=sys.stderr)
    print(f"theia vs pbrt-v4, {a.spp} spp, {a.runs} interleaved runs each; CPU = user + sys of the whole process; "
          f"{load_note(load_before)}")
    print("\n".join(comparison_table(rows)))
    print("\nMedians of the per-round CPU-s ratios (each round's runs share the same minutes):")
    print("\n".join(paired_lines))


if __name__ == "__main__":
    main()
