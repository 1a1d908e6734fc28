#!/usr/bin/python3
"""Error against run time: plots and a Markdown report from render logs.

  error_report.py report LOG.json [LOG.json ...] [--baseline LABEL] [--out DIR]
      Logs written by `theia render --reference REF.exr` (or by `matrix` for an
      external renderer).  Per scene: relMSE against render time and against
      spp (log-log), time to reach a relMSE (log-log interpolation) and the
      efficiency of each configuration against the baseline
      (baseline time / its time to the same error; > 1 is faster).

  error_report.py matrix [--theia build/theia] [--spp N] [--out DIR]
                         [--external 'CMD {spp} {out}' --external-name NAME
                          --external-spp 4,16,64]
      Runs the standard matrix (SCENES x CONFIGURATIONS below) with --reference,
      optionally an external renderer at a series of spp, then `report`.

  error_report.py seeds SCENE [--spp 256] [--seeds 12] [--out DIR] [-- THEIA-ARGS]
      Renders SCENE (a name from SCENES) at --spp with seeds 0..N-1 and checks
      each render against issue #3's bar (relMSE <= 2x pbrt-v4's own 256-spp
      render, 8x8-block relMSE <= max(3x, 5e-4), channel-mean deviation <=
      pbrt-v4's + 0.02).  For a heavy-tailed estimator one seed says little:
      this reports how often the bar is met, and how much of each render's
      relMSE its worst pixel holds (one firefly, or noise everywhere).

  error_report.py equal-time [--scenes a,b] [--budgets 2,8,32] [--seeds 3]
                             [--config NAME=ARGS ...] [--spp CAP] [--out DIR]
      Equal-time comparison (issue 12): renders each scene under each
      `--time-limit` budget with seeds 0..N-1 and each configuration
      (default: unguided = --no-guiding, guided = --guiding; --config
      auto=--guiding-auto adds one; the first is the baseline), and writes a
      Markdown table of the median over seeds of relMSE and MAPE against the
      reference (and their ratio to the baseline), the variance across seeds,
      the spp reached, time per spp, path length, SD-tree leaves and the
      guide-draw failure rate where the log has them ("-" where it does not).
      A scene without a reference in tests/data gets one rendered once
      (unguided, --reference-spp, cached in --out).

Needs Debian's python3-numpy, python3-matplotlib, python3-openimageio
(tools/install-deps.sh).  Run with /usr/bin/python3.
"""
import argparse
import json
import os
import shlex
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# The standard matrix.  Later features add their configurations here (guiding,
# cache points, ...); the first one is the default baseline.
CONFIGURATIONS = [
    ("default", []),
    ("sort-off", ["--sort", "off"]),
    ("light-uniform", ["--light-sampler", "uniform"]),
    ("batch-4k", ["--batch-size", "4096"]),
    ("batch-1m", ["--batch-size", "1048576"]),
]
SCENES = [
    ("cornell-box", "scenes/cornell-box/scene.pbrt", "tests/data/cornell-box.exr"),
    ("veach-mis", "scenes/veach-mis/scene.pbrt", "tests/data/veach-mis.exr"),
]
# The validation scenes (`seeds`): the matrix above plus the rest.
VALIDATION_SCENES = SCENES + [
    ("living-room", "scenes/living-room/scene.pbrt", "tests/data/living-room.exr"),
    ("material-testball", "scenes/material-testball/scene.pbrt", "tests/data/material-testball.exr"),
    ("veach-ajar", "scenes/veach-ajar/scene.pbrt", "tests/data/veach-ajar.exr"),
]
# pbrt-v4's own 256-spp render against the reference (as tests/e2e/test_validation.cpp):
# relMSE, 8x8-block relMSE, channel-mean deviation.
PBRT_256 = {
    "cornell-box": (0.00079, 1.3e-5, 0.0013),
    "veach-mis": (0.0359, 0.00066, 0.0122),
    "material-testball": (0.0256, 0.00123, 0.0021),
    "living-room": (0.0055, 7.6e-5, 0.0003),
    "veach-ajar": (0.679, 0.0093, 0.0046),
}
REL_EPS = 1e-2  # as core/metrics.h

# `equal-time`: issue 12's scenes and configurations (the first is the baseline).
# guiding-panel's reference is theia's own at 262144 spp, guided by the mixture field (seed 1000, independent
# of the measured seeds 0..N): `theia render scenes/guiding-panel/scene.pbrt --spp 262144 --seed 1000
# --threads 1 --guiding --guiding-field vmm`; its relMSE is about 4e-7 (vmm's per-sample error at 2048 spp
# scaled), a three-hundredth of an unguided 30-second render's.  Against the unguided 262144-spp reference it replaced
# (seed 4242) relMSE is 1.04e-5, that one's own error, with 8x8-block relMSE 2.1e-7 and means within 0.01%.
EQUAL_TIME_SCENES = VALIDATION_SCENES + [("guiding-panel", "scenes/guiding-panel/scene.pbrt",
                                          "tests/data/guiding-panel.exr"),
                                         ("fog-slit", "scenes/fog-slit/scene.pbrt", None)]
EQUAL_TIME_DEFAULT_SCENES = ["guiding-panel", "cornell-box", "living-room", "material-testball", "veach-mis",
                             "veach-ajar"]
# theia's own default is --guiding-auto: the baseline says --no-guiding.
EQUAL_TIME_CONFIGURATIONS = [("unguided", ["--no-guiding"]), ("guided", ["--guiding"])]
# Where a render log may hold the guide-draw failure rate (the share of guided
# draws that end the path); the first key found anywhere in the log is used.
GUIDE_FAILURE_KEYS = ("guide_draw_failure_rate", "draw_failure_rate", "guide_failure_rate")


# ---------------------------------------------------------------- metrics


def read_rgb(path):
    import OpenImageIO as oiio
    buf = oiio.ImageBuf(path)
    if buf.has_error:
        sys.exit(f"{path}: {buf.geterror()}")
    px = buf.get_pixels(oiio.FLOAT)
    if px is None or px.ndim != 3 or px.shape[2] < 3:
        sys.exit(f"{path}: expected an RGB image")
    return px[:, :, :3].astype(np.float64)


def error_metrics(x, r):
    if x.shape != r.shape:
        raise ValueError(f"image sizes differ: {x.shape} vs reference {r.shape}")
    d = x - r
    return {"rel_mse": float(np.mean(d * d / (r * r + REL_EPS))),
            "rmse": float(np.sqrt(np.mean(d * d))),
            "mape": float(np.mean(np.abs(d) / (np.abs(r) + REL_EPS)))}


def bar(pbrt):
    """Issue #3's bar from pbrt-v4's (relMSE, block relMSE, deviation)."""
    rel, block, dev = pbrt
    return (2.0 * rel, max(3.0 * block, 5e-4), dev + 0.02)


def meets_bar(metrics, pbrt):
    limits = bar(pbrt)
    values = (metrics["rel_mse"], metrics["block_rel_mse"], metrics["channel_mean_deviation"])
    return all(v <= limit for v, limit in zip(values, limits))


def parse_diff(text):
    """The `key value` lines `theia diff` prints (tiles and the like skipped)."""
    out = {}
    for line in text.splitlines():
        parts = line.split()
        if len(parts) == 2:
            try:
                out[parts[0]] = float(parts[1])
            except ValueError:
                pass
    return out


def worst_pixel(x, r):
    """(x, y) of the pixel holding the most relMSE, and its share of the total."""
    d = x - r
    per_pixel = np.sum(d * d / (r * r + REL_EPS), axis=2)
    total = float(per_pixel.sum())
    y, xx = np.unravel_index(int(np.argmax(per_pixel)), per_pixel.shape)
    return (int(xx), int(y)), (float(per_pixel[y, xx]) / total if total > 0 else 0.0)


# ---------------------------------------------------------------- logs


def load_curve(path, label=None):
    """(scene, label, arrays spp/seconds/rel_mse) from a theia or external log."""
    with open(path) as f:
        log = json.load(f)
    its = [it for it in log.get("scheduler", {}).get("iterations", []) if "rel_mse" in it]
    if not its:
        sys.exit(f"{path}: no per-iteration error; render with --reference")
    scene = log.get("scene_name") or os.path.basename(os.path.dirname(log.get("scene", ""))) or "scene"
    label = label or log.get("label") or os.path.splitext(os.path.basename(path))[0]
    return {"scene": scene, "label": label, "path": path,
            "spp": np.array([it["spp_total"] for it in its], float),
            "seconds": np.array([it["render_seconds"] for it in its], float),
            "rel_mse": np.array([it["rel_mse"] for it in its], float)}


def time_to_error(curve, target):
    """Render time at which the curve reaches `target` relMSE, interpolated
    linearly in log-log; None if it never gets there."""
    e, t = curve["rel_mse"], curve["seconds"]
    if e[0] <= target:
        # Reached at the first boundary: extrapolate back along an 1/t slope.
        return float(t[0] * e[0] / target) if e[0] > 0 else float(t[0])
    for i in range(1, len(e)):
        if e[i] <= target:
            a = (np.log(target) - np.log(e[i - 1])) / (np.log(e[i]) - np.log(e[i - 1]))
            return float(np.exp(np.log(t[i - 1]) + a * (np.log(t[i]) - np.log(t[i - 1]))))
    return None


def error_targets(curves):
    """Three relMSE levels every curve of a scene passes through."""
    hi = min(c["rel_mse"].max() for c in curves)
    lo = max(c["rel_mse"].min() for c in curves)
    if lo >= hi:
        lo = hi
    return sorted({float(v) for v in np.geomspace(hi, lo, 3)}, reverse=True)


# ---------------------------------------------------------------- report


def plot_scene(scene, curves, out_dir):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for c in curves:
        axes[0].loglog(c["seconds"], c["rel_mse"], "o-", ms=3, label=c["label"])
        axes[1].loglog(c["spp"], c["rel_mse"], "o-", ms=3, label=c["label"])
    axes[0].set_xlabel("render time [s]")
    axes[1].set_xlabel("samples per pixel")
    for ax in axes:
        ax.set_ylabel("relMSE")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{scene}: error against time and spp")
    fig.tight_layout()
    path = os.path.join(out_dir, f"{scene}.png")
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def report(curves, baseline, out_dir):
    os.makedirs(out_dir, exist_ok=True)
    scenes = {}
    for c in curves:
        scenes.setdefault(c["scene"], []).append(c)
    lines = ["# Error against run time", "",
             "relMSE = mean over pixels and RGB of (x - r)^2 / (r^2 + 0.01) against the reference; "
             "time is render time (scene loading and error measurement excluded). "
             f"Efficiency = time of `{baseline}` / time of the configuration to reach the same relMSE "
             "(> 1: faster), interpolated log-log.", ""]
    for scene, cs in scenes.items():
        png = plot_scene(scene, cs, out_dir)
        base = next((c for c in cs if c["label"] == baseline), cs[0])
        targets = error_targets(cs)
        lines += [f"## {scene}", "", f"![{scene}]({os.path.basename(png)})", "",
                  "| configuration | final spp | final time [s] | final relMSE | "
                  + " | ".join(f"time to {t:.3g} [s]" for t in targets) + " | "
                  + " | ".join(f"efficiency at {t:.3g}" for t in targets) + " |",
                  "|---" * (4 + 2 * len(targets)) + "|"]
        base_times = [time_to_error(base, t) for t in targets]
        for c in cs:
            times = [time_to_error(c, t) for t in targets]
            eff = [f"{b / t:.2f}" if (b and t) else "-" for b, t in zip(base_times, times)]
            lines.append(f"| {c['label']} | {c['spp'][-1]:.0f} | {c['seconds'][-1]:.2f} | {c['rel_mse'][-1]:.4g} | "
                         + " | ".join(f"{t:.3f}" if t else "-" for t in times) + " | " + " | ".join(eff) + " |")
        lines.append("")
    path = os.path.join(out_dir, "report.md")
    with open(path, "w") as f:
        f.write("\n".join(lines))
    print(f"wrote {path}")
    return path


# ---------------------------------------------------------------- running


def run_theia(theia, scene_name, scene, ref, label, args, spp, out_dir):
    out = os.path.join(out_dir, f"{scene_name}-{label}.exr")
    log = os.path.splitext(out)[0] + ".json"
    cmd = [theia, "render", scene, "-o", out, "--spp", str(spp), "--reference", ref, "-q"] + args
    print(" ".join(shlex.quote(a) for a in cmd), flush=True)
    subprocess.run(cmd, check=True)
    with open(log) as f:
        data = json.load(f)
    data["label"], data["scene_name"] = label, scene_name
    with open(log, "w") as f:
        json.dump(data, f, indent=1)
    return log


def run_external(template, name, scene_name, scene, ref, spps, out_dir):
    """Runs `template` (with {spp}, {out}, {scene}) at each spp, times it and
    writes a log in theia's format so `report` plots it on the same axes."""
    reference = read_rgb(ref)
    its = []
    for spp in spps:
        out = os.path.join(out_dir, f"{scene_name}-{name}-{spp}.exr")
        cmd = template.format(spp=spp, out=shlex.quote(out), scene=shlex.quote(scene))
        print(cmd, flush=True)
        t0 = time.monotonic()
        subprocess.run(cmd, shell=True, check=True)
        seconds = time.monotonic() - t0
        m = error_metrics(read_rgb(out), reference)
        its.append({"spp_total": spp, "render_seconds": seconds, "wall_seconds": seconds, **m})
    log = os.path.join(out_dir, f"{scene_name}-{name}.json")
    with open(log, "w") as f:
        json.dump({"scene": scene, "scene_name": scene_name, "label": name,
                   "note": "external renderer: times include its scene loading",
                   "scheduler": {"iterations": its}}, f, indent=1)
    return log


def seeds(theia, scene_name, spp, n, out_dir, extra):
    scenes = {sc[0]: sc for sc in VALIDATION_SCENES}
    if scene_name not in scenes:
        sys.exit(f"unknown scene {scene_name}; known: {', '.join(scenes)}")
    _, scene, ref = scenes[scene_name]
    scene, ref = os.path.join(ROOT, scene), os.path.join(ROOT, ref)
    reference = read_rgb(ref)
    os.makedirs(out_dir, exist_ok=True)
    limits = bar(PBRT_256[scene_name])
    lines = [f"# {scene_name} at {spp} spp over {n} seeds", "",
             f"Bar: relMSE <= {limits[0]:.4g}, block relMSE <= {limits[1]:.3g}, "
             f"mean deviation <= {limits[2]:.4g} (pbrt-v4 at 256 spp: {PBRT_256[scene_name]}).", "",
             "| seed | relMSE | block relMSE | mean deviation | worst pixel | its share of relMSE | bar |",
             "|---|---|---|---|---|---|---|"]
    passed, rels = 0, []
    for seed in range(n):
        out = os.path.join(out_dir, f"{scene_name}-seed{seed}.exr")
        cmd = [theia, "render", scene, "-o", out, "--spp", str(spp), "--seed", str(seed), "-q"] + extra
        print(" ".join(shlex.quote(c) for c in cmd), flush=True)
        subprocess.run(cmd, check=True)
        diff = subprocess.run([theia, "diff", out, ref], check=True, capture_output=True, text=True).stdout
        d = parse_diff(diff)
        m = {"rel_mse": d["relMSE"], "block_rel_mse": d["block_relMSE"],
             "channel_mean_deviation": d["channel_mean_deviation"]}
        ok = meets_bar(m, PBRT_256[scene_name])
        passed += ok
        rels.append(m["rel_mse"])
        (px, py), share = worst_pixel(read_rgb(out), reference)
        lines.append(f"| {seed} | {m['rel_mse']:.4g} | {m['block_rel_mse']:.3g} | {m['channel_mean_deviation']:.4f} "
                     f"| ({px}, {py}) | {share:.0%} | {'meets' if ok else '**misses**'} |")
    lines += ["", f"{passed} of {n} seeds meet the bar; median relMSE {float(np.median(rels)):.4g}.", ""]
    path = os.path.join(out_dir, f"{scene_name}-seeds.md")
    with open(path, "w") as f:
        f.write("\n".join(lines))
    print("\n".join(lines))
    print(f"wrote {path}")
    return passed


# ---------------------------------------------------------------- equal time


def find_key(tree, keys):
    """The value of the first of `keys` found anywhere in a JSON tree (depth first), or None."""
    if isinstance(tree, dict):
        for k in keys:
            if k in tree and isinstance(tree[k], (int, float)):
                return float(tree[k])
        for v in tree.values():
            found = find_key(v, keys)
            if found is not None:
                return found
    return None


def log_statistics(log):
    """What an equal-time row reports from a render's log (None where absent)."""
    w, h = log.get("resolution", [0, 0])
    camera = log.get("rays", {}).get("camera")
    render = log.get("time", {}).get("render")
    spp = log.get("scheduler", {}).get("spp_per_pixel", {})
    mean_spp = camera / (w * h) if camera and w and h else None
    return {"seconds_per_spp": render / mean_spp if render is not None and mean_spp else None,
            "spp_min": spp.get("min"), "spp_max": spp.get("max"),
            "path_length": log.get("paths", {}).get("average_length"),
            "leaves": log.get("guiding", {}).get("spatial_leaves"),
            "guide_failure_rate": find_key(log, GUIDE_FAILURE_KEYS),
            # --guiding-auto's verdict (on / off / provisional ...), None without auto.
            "verdict": log.get("guiding", {}).get("auto", {}).get("verdict")}


EQUAL_TIME_METRICS = ("rel_mse", "mape", "seconds_per_spp", "spp_min", "spp_max", "path_length", "leaves",
                      "guide_failure_rate", "seed_variance")


def aggregate(rows):
    """Rows (one per scene, configuration, budget and seed) to one group per
    (scene, configuration, budget), in first-seen order: the median over
    seeds of every metric (None where no seed has it) and the seed count."""
    groups = {}
    for r in rows:
        groups.setdefault((r["scene"], r["configuration"], r["budget"]), []).append(r)
    out = []
    for (scene, config, budget), rs in groups.items():
        g = {"scene": scene, "configuration": config, "budget": budget, "seeds": len(rs)}
        for m in EQUAL_TIME_METRICS:
            values = [r[m] for r in rs if r.get(m) is not None]
            g[m] = float(np.median(values)) if values else None
        verdicts = [r["verdict"] for r in rs if r.get("verdict")]
        g["verdicts"] = ", ".join(verdicts) if verdicts else None  # seed by seed
        out.append(g)
    return out


def equal_time_table(groups, baseline):
    """Markdown lines: one row per group; relMSE also as a ratio to the
    baseline configuration's at the same scene and budget."""
    base = {(g["scene"], g["budget"]): g for g in groups if g["configuration"] == baseline}

    def num(v, fmt="{:.4g}"):
        return "-" if v is None else fmt.format(v)

    lines = ["| scene | configuration | budget [s] | seeds | spp (min-max) | relMSE | relMSE / "
             f"{baseline} | MAPE | variance across seeds | time per spp [s] | path length | leaves | "
             "guide-draw failures | auto verdicts |",
             "|---" * 14 + "|"]
    for g in groups:
        b = base.get((g["scene"], g["budget"]))
        ratio = g["rel_mse"] / b["rel_mse"] if b and g["rel_mse"] is not None and b["rel_mse"] else None
        spp = "-" if g["spp_min"] is None else f"{g['spp_min']:.0f}-{g['spp_max']:.0f}"
        lines.append(f"| {g['scene']} | {g['configuration']} | {g['budget']:g} | {g['seeds']} | {spp} | "
                     f"{num(g['rel_mse'])} | {num(ratio, '{:.3f}')} | {num(g['mape'])} | {num(g['seed_variance'])} | "
                     f"{num(g['seconds_per_spp'], '{:.4f}')} | {num(g['path_length'], '{:.2f}')} | "
                     f"{num(g['leaves'], '{:.0f}')} | {num(g['guide_failure_rate'], '{:.1%}')} | "
                     f"{g.get('verdicts') or '-'} |")
    return lines


def seed_variance(images):
    """Mean over pixels and RGB of the per-pixel sample variance across seeds' images."""
    if len(images) < 2:
        return None
    return float(np.mean(np.var(np.stack(images), axis=0, ddof=1)))


def parse_configuration(text):
    """'NAME=ARGS' (ARGS split as a shell would) to (name, [args])."""
    name, _, args = text.partition("=")
    if not name:
        sys.exit(f"--config {text}: expected NAME=ARGS")
    return name, shlex.split(args)


def configuration_binaries(texts, configurations, default):
    """'NAME=PATH' per --config-theia to {name: binary} over every configuration (default: --theia), so
    that a base and a changed build render side by side under the same load."""
    names = [label for label, _ in configurations]
    binaries = {label: default for label in names}
    for text in texts or []:
        name, _, path = text.partition("=")
        if not name or not path:
            sys.exit(f"--config-theia {text}: expected NAME=PATH")
        if name not in binaries:
            sys.exit(f"--config-theia {text}: no configuration {name}; configurations: {', '.join(names)}")
        binaries[name] = path
    return binaries


def equal_time_reference(theia, name, scene, ref, spp, out_dir):
    if ref:
        return os.path.join(ROOT, ref)
    path = os.path.join(out_dir, f"{name}-reference.exr")
    if not os.path.exists(path):
        cmd = [theia, "render", scene, "-o", path, "--spp", str(spp), "--seed", "1000003", "-q", "--no-guiding"]
        print(" ".join(shlex.quote(a) for a in cmd), flush=True)
        subprocess.run(cmd, check=True)
    return path


def run_side_by_side(cmds):
    """Runs the commands at once and waits for all of them (each must succeed)."""
    procs = [subprocess.Popen(cmd) for cmd in cmds]
    codes = [p.wait() for p in procs]
    for cmd, code in zip(cmds, codes):
        if code != 0:
            raise subprocess.CalledProcessError(code, cmd)


def equal_time(theia, scene_names, budgets, n_seeds, configurations, spp_cap, reference_spp, out_dir,
               side_by_side=False, binaries=None):
    binaries = binaries or {label: theia for label, _ in configurations}
    scenes = {sc[0]: sc for sc in EQUAL_TIME_SCENES}
    os.makedirs(out_dir, exist_ok=True)
    rows = []
    threads = max(1, (os.cpu_count() or 1) // len(configurations))
    for name in scene_names:
        if name not in scenes:
            sys.exit(f"--scenes: unknown scene {name}; known: {', '.join(scenes)}")
        _, scene, ref = scenes[name]
        scene = os.path.join(ROOT, scene)
        reference = read_rgb(equal_time_reference(theia, name, scene, ref, reference_spp, out_dir))
        # Configurations interleaved within each seed: the machine's load drifts,
        # and each configuration's renders should see the same share of it.
        # Side by side, they run at the same time on an equal share of the
        # cores, so that they see the very same load.
        for budget in budgets:
            images = {label: [] for label, _ in configurations}
            groups = {label: [] for label, _ in configurations}
            for seed in range(n_seeds):
                outs, cmds = [], []
                for label, args in configurations:
                    out = os.path.join(out_dir, f"{name}-{label}-{budget:g}s-seed{seed}.exr")
                    cmd = [binaries[label], "render", scene, "-o", out, "--spp", str(spp_cap),
                           "--time-limit", f"{budget:g}", "--seed", str(seed), "-q"] + args
                    if side_by_side:
                        cmd += ["--threads", str(threads)]
                    print(" ".join(shlex.quote(a) for a in cmd), flush=True)
                    outs.append(out)
                    cmds.append(cmd)
                    if not side_by_side:
                        subprocess.run(cmd, check=True)
                if side_by_side:
                    run_side_by_side(cmds)
                for (label, _), out in zip(configurations, outs):
                    with open(os.path.splitext(out)[0] + ".json") as f:
                        log = json.load(f)
                    image = read_rgb(out)
                    images[label].append(image)
                    groups[label].append({"scene": name, "configuration": label, "budget": budget, "seed": seed,
                                          **error_metrics(image, reference), **log_statistics(log)})
            for label, _ in configurations:
                v = seed_variance(images[label])
                for r in groups[label]:
                    r["seed_variance"] = v
                rows += groups[label]
    groups = aggregate(rows)
    how = (f" The configurations of a seed ran side by side, each with `--threads {threads}`."
           if side_by_side else "")
    if len(set(binaries.values())) > 1:
        how += " Binaries: " + ", ".join(f"{label} `{binaries[label]}`" for label, _ in configurations) + "."
    lines = [f"# Equal time: median of {n_seeds} seeds", "",
             "Each render: `theia render SCENE --spp " + str(spp_cap) + " --time-limit BUDGET --seed S` plus the "
             "configuration's arguments; relMSE and MAPE against the reference (tests/data, or rendered unguided at "
             f"{reference_spp} spp), time per spp = render time / mean spp, path length in vertices." + how, "",
             "Configurations: " + ", ".join(f"{label} = `{' '.join(args) or '(none)'}`"
                                            for label, args in configurations), ""]
    lines += equal_time_table(groups, configurations[0][0]) + [""]
    path = os.path.join(out_dir, "equal-time.md")
    with open(path, "w") as f:
        f.write("\n".join(lines))
    with open(os.path.join(out_dir, "equal-time.json"), "w") as f:
        json.dump(rows, f, indent=1)
    print("\n".join(lines))
    print(f"wrote {path}")
    return groups


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True)
    rp = sub.add_parser("report", help="plots and Markdown from logs")
    rp.add_argument("logs", nargs="+")
    rp.add_argument("--baseline", default=CONFIGURATIONS[0][0])
    rp.add_argument("--out", default="out/report")
    mp = sub.add_parser("matrix", help="run scenes x configurations, then report")
    mp.add_argument("--theia", default=os.path.join(ROOT, "build", "theia"))
    mp.add_argument("--spp", type=int, default=256)
    mp.add_argument("--out", default="out/report")
    mp.add_argument("--scenes", default=",".join(s[0] for s in SCENES))
    mp.add_argument("--configurations", default=",".join(c[0] for c in CONFIGURATIONS))
    mp.add_argument("--external", help="command template with {spp} and {out} (and optionally {scene})")
    mp.add_argument("--external-name", default="external")
    mp.add_argument("--external-spp", default="4,8,16,32,64,128")
    sp = sub.add_parser("seeds", help="one scene over many seeds against the validation bar")
    sp.add_argument("scene")
    sp.add_argument("--theia", default=os.path.join(ROOT, "build", "theia"))
    sp.add_argument("--spp", type=int, default=256)
    sp.add_argument("--seeds", type=int, default=12)
    sp.add_argument("--out", default="out/seeds")
    ep = sub.add_parser("equal-time", help="configurations at equal render time (--time-limit), median of seeds")
    ep.add_argument("--theia", default=os.path.join(ROOT, "build", "theia"))
    ep.add_argument("--scenes", default=",".join(EQUAL_TIME_DEFAULT_SCENES))
    ep.add_argument("--budgets", default="2,8,32", help="seconds of render time, comma-separated")
    ep.add_argument("--seeds", type=int, default=3)
    ep.add_argument("--config", action="append", metavar="NAME=ARGS",
                    help="a configuration (repeatable; the first is the baseline); default: "
                    + ", ".join(f"{n}={' '.join(a)}" for n, a in EQUAL_TIME_CONFIGURATIONS))
    ep.add_argument("--config-theia", action="append", metavar="NAME=PATH",
                    help="render configuration NAME with this theia instead of --theia (repeatable): a base build "
                    "against a changed one, interleaved or side by side")
    ep.add_argument("--spp", type=int, default=65536, help="upper bound on spp (the time limit ends the renders)")
    ep.add_argument("--reference-spp", type=int, default=4096)
    ep.add_argument("--out", default="out/equal-time")
    ep.add_argument("--side-by-side", action="store_true",
                    help="run a seed's configurations at the same time, each on cores / configurations threads, "
                    "so that they share the machine's load (a budget then buys that many cores' time)")
    # Everything after "--" goes to `theia render` (argparse's subparsers would take it as theirs).
    argv = sys.argv[1:]
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    a = ap.parse_args(argv[:argv.index("--")] if "--" in argv else argv)

    if a.command == "equal-time":
        configs = [parse_configuration(c) for c in a.config] if a.config else EQUAL_TIME_CONFIGURATIONS
        equal_time(a.theia, a.scenes.split(","), [float(b) for b in a.budgets.split(",")], a.seeds, configs,
                   a.spp, a.reference_spp, a.out, a.side_by_side,
                   configuration_binaries(a.config_theia, configs, a.theia))
        return
    if a.command == "seeds":
        seeds(a.theia, a.scene, a.spp, a.seeds, a.out, extra)
        return
    if a.command == "report":
        report([load_curve(p) for p in a.logs], a.baseline, a.out)
        return
    os.makedirs(a.out, exist_ok=True)
    scenes = {s[0]: s for s in SCENES}
    configs = dict(CONFIGURATIONS)
    logs = []
    t0 = time.monotonic()
    for name in a.scenes.split(","):
        if name not in scenes:
            sys.exit(f"--scenes: unknown scene {name}; known: {', '.join(scenes)}")
        _, scene, ref = scenes[name]
        scene, ref = os.path.join(ROOT, scene), os.path.join(ROOT, ref)
        for label in a.configurations.split(","):
            if label not in configs:
                sys.exit(f"--configurations: unknown {label}; known: {', '.join(configs)}")
            logs.append(run_theia(a.theia, name, scene, ref, label, configs[label], a.spp, a.out))
        if a.external:
            spps = [int(s) for s in a.external_spp.split(",")]
            logs.append(run_external(a.external, a.external_name, name, scene, ref, spps, a.out))
    print(f"matrix: {len(logs)} runs in {time.monotonic() - t0:.1f} s", flush=True)
    report([load_curve(p) for p in logs], a.configurations.split(",")[0], a.out)


if __name__ == "__main__":
    main()
