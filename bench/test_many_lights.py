#!/usr/bin/python3
"""Tests of many_lights.py's parsing and figures (run by CTest, label `tools`).

No renderer runs here: `theia diff` output, scene headers and rows are given,
so every figure can be checked against its definition."""
import contextlib
import io
import os
import re
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import compare_pbrt as cp  # noqa: E402
import many_lights as ml  # noqa: E402

DIFF_OUTPUT = """relMSE 0.117000001
RMSE 0.0123
MAPE 0.25
block_relMSE 0.00055
channel_mean_deviation 0.0135
channel_mean_ratio 1.0135 0.995 0.9901
worst 32x32 tiles (x0 y0 x1 y1 relMSE mean_ratio_R mean_ratio_G mean_ratio_B):
tile 0 0 32 32 0.5 1.0000 1.0000 1.0000
"""


class DiffFigures(unittest.TestCase):
    def test_relmse_and_signed_mean_ratios(self):
        f = ml.diff_figures(DIFF_OUTPUT)
        self.assertAlmostEqual(f["rel_mse"], 0.117000001)  # not block_relMSE, not a tile's
        self.assertEqual(f["mean_ratio"], [1.0135, 0.995, 0.9901])

    def test_output_without_a_figure_is_an_error(self):
        old = DIFF_OUTPUT.replace("channel_mean_ratio 1.0135 0.995 0.9901\n", "")
        with self.assertRaises(SystemExit):
            ml.diff_figures(old)
        with self.assertRaises(SystemExit):
            ml.diff_figures(DIFF_OUTPUT.replace("relMSE 0.117000001\n", ""))


class PbrtIntegrator(unittest.TestCase):
    def test_light_sampler_from_the_integrator_directive(self):
        text = ('# Integrator "path" "string lightsampler" "power" (a comment)\n'
                'Integrator "volpath" "integer maxdepth" [ 8 ]\n'
                '    "string lightsampler" [ "uniform" ]\n'
                'Sampler "zsobol" "integer pixelsamples" [ 64 ]\nWorldBegin\n')
        self.assertEqual(ml.pbrt_integrator(text), ("volpath", "uniform"))
        self.assertEqual(ml.pbrt_integrator('Integrator "path" "string lightsampler" "power"\nWorldBegin\n'),
                         ("path", "power"))

    def test_pbrt_defaults_where_unset(self):
        self.assertEqual(ml.pbrt_integrator('Integrator "path" "integer maxdepth" 5\nFilm "rgb"\nWorldBegin\n'),
                         ("path", "bvh"))
        self.assertEqual(ml.pbrt_integrator('Film "rgb"\nWorldBegin\nShape "sphere"\n'), ("volpath", "bvh"))

    def test_a_light_sampler_of_another_directive_does_not_count(self):
        text = ('Integrator "bdpt"\nSampler "zsobol" "string lightsampler" "power"\nWorldBegin\n'
                'Integrator "path"\n')
        self.assertEqual(ml.pbrt_integrator(text), ("bdpt", "bvh"))

    def setUp(self):
        tmp = tempfile.TemporaryDirectory()
        self.addCleanup(tmp.cleanup)
        self.dir = tmp.name

    def scene(self, name, text=""):
        path = os.path.join(self.dir, name)
        with open(path, "w") as f:
            f.write(text)
        return path

    def test_only_the_bvh_light_sampler_is_accepted(self):
        for bad in ('Integrator "bdpt"\nWorldBegin\n', 'Integrator "volpath" "string lightsampler" "power"\n'):
            with self.assertRaises(SystemExit):
                ml.check_pbrt_scene(self.scene("bad.pbrt", bad))
        ml.check_pbrt_scene(self.scene("good.pbrt", 'Integrator "path" "string lightsampler" "bvh"\nWorldBegin\n'))

    def test_the_benchmark_scenes_use_pbrt_v4s_bvh(self):
        city = os.path.join(HERE, "..", "scenes", "many-lights-city", "scene.pbrt")
        with open(city) as f:
            self.assertEqual(ml.pbrt_integrator(f.read()), ("volpath", "bvh"))
        street = self.scene("street.pbrt")
        subprocess.run([sys.executable, os.path.join(HERE, "make_street.py"), "--n", "2", "--output", street],
                       check=True)
        with open(street) as f:
            self.assertEqual(ml.pbrt_integrator(f.read()), ("volpath", "bvh"))


def emissive_meshes(text):
    """Per AreaLightSource, the triangle count of the trianglemesh shapes up to the next one (or the end)."""
    counts = []
    for part in text.split("AreaLightSource")[1:]:
        indices = re.findall(r'"integer indices"\s*\[([^\]]*)\]', part)
        counts.append(sum(len(i.split()) for i in indices) // 3)
    return counts


class GeneratedScenes(unittest.TestCase):
    """--city100k and --mesh100k: the same 100,000 emissive triangles, as 100-odd lights or one mesh light."""

    def test_variants_hold_100k_emissive_triangles(self):
        with tempfile.TemporaryDirectory() as tmp:
            city = ml.make_variant(tmp, "city100k")
            with open(city) as f:
                city_text = f.read()
            mesh = ml.make_variant(tmp, "mesh100k")
            with open(mesh) as f:
                mesh_text = f.read()
        self.assertEqual(sum(emissive_meshes(city_text)), 100000)
        self.assertGreater(len(emissive_meshes(city_text)), 1)
        self.assertEqual(emissive_meshes(mesh_text), [100000])
        for text in (city_text, mesh_text):
            self.assertEqual(ml.pbrt_integrator(text), ("volpath", "bvh"))
        # The same geometry: the emitters' vertices, as numbers, are the city's.
        def emitter_points(text):
            section = text.split('MakeNamedMaterial "emitter"')[1]
            return sorted(v for p in re.findall(r'"point3 P" \[([^\]]*)\]', section) for v in p.split())
        self.assertEqual(emitter_points(city_text), emitter_points(mesh_text))

    def test_one_variant_at_a_time(self):
        with self.assertRaises(SystemExit):
            with contextlib.redirect_stderr(io.StringIO()):
                self.addCleanup(setattr, sys, "argv", sys.argv)
                sys.argv = ["many_lights.py", "--city100k", "--mesh100k"]
                ml.main()


def row(sampler, run, rel_mse, total, cpu, peak, ratio, build=0.0):
    r = {"sampler": sampler, "run": run, "rel_mse": rel_mse, "total_seconds": total, "cpu_seconds": cpu,
         "peak_mib": peak, "mean_ratio": ratio}
    if sampler != ml.PBRT_ROW:
        r["build_seconds"] = build
    return r


ROWS = [row("uniform", 0, 2.0, 1.0, 2.0, 30, [1.0, 1.0, 1.0]),
        row("uniform", 1, 4.0, 3.0, 4.0, 33, [1.2, 1.0, 0.8]),
        row("uniform", 2, 3.0, 2.0, 3.0, 31, [1.1, 1.0, 0.9]),
        row("bvh", 0, 0.1, 2.0, 4.0, 40, [1.02, 1.0, 0.98], 0.2),
        row("bvh", 1, 0.3, 2.0, 4.0, 41, [1.0, 1.0, 1.0], 0.2),
        row("bvh", 2, 0.2, 2.0, 4.0, 39, [1.01, 1.0, 0.99], 0.2),
        row(ml.PBRT_ROW, 0, 0.5, 6.0, 5.0, 20, [1.03, 0.98, 1.01]),
        row(ml.PBRT_ROW, 1, 0.4, 4.0, 6.0, 21, [1.05, 1.0, 0.97]),
        row(ml.PBRT_ROW, 2, 0.6, 5.0, 4.0, 19, [1.01, 0.99, 0.99])]


class Figures(unittest.TestCase):
    def test_mean_ratio_is_the_median_per_channel(self):
        self.assertEqual(ml.median_ratio(ROWS, "uniform"), [1.1, 1.0, 0.9])
        self.assertEqual(ml.median_ratio(ROWS, ml.PBRT_ROW), [1.03, 0.99, 0.99])

    def test_pbrt_is_compared_with_theias_least_noisy_sampler(self):
        best, ratio = ml.pbrt_over_theia(ROWS, ["uniform", "bvh"])
        self.assertEqual(best, "bvh")
        for got, want in zip(ratio, [1.03 / 1.01, 0.99 / 1.0, 0.99 / 0.99]):
            self.assertAlmostEqual(got, want)

    def test_table_rows_are_time_to_unit_variance_beside_theias_samplers(self):
        lines = ml.summary_table(ROWS, ["uniform", "bvh", ml.PBRT_ROW])
        self.assertEqual(len(lines), 5)
        # uniform: relMSE 3, wall 2, CPU 3 (medians): TUV 6 and 9, the base of every ratio.
        self.assertEqual(lines[2], "| uniform | 3.0000 | 2.0 (0.0) | 3.0 | 6.000 (1.0x) | 9.000 (1.0x) | 33 "
                                   "| 1.100 1.000 0.900 |")
        self.assertEqual(lines[3], "| bvh | 0.2000 | 2.0 (0.2) | 4.0 | 0.400 (15.0x) | 0.800 (11.2x) | 41 "
                                   "| 1.010 1.000 0.990 |")
        # pbrt-v4: relMSE 0.5, process wall 5, CPU 5: TUV 2.5 (6 / 2.5 = 2.4x) and 2.5 (9 / 2.5 = 3.6x); no build.
        self.assertEqual(lines[4], "| pbrt-v4 | 0.5000 | 5.0 (-) | 5.0 | 2.500 (2.4x) | 2.500 (3.6x) | 21 "
                                   "| 1.030 0.990 0.990 |")


class Commands(unittest.TestCase):
    def test_pbrt_renders_with_the_runs_seed_at_its_own_spp(self):
        class Args:
            pbrt, pbrt_spp = "/opt/pbrt", 48
        calls = []
        ml.run_measured = lambda cmd, log: calls.append((cmd, log))
        self.addCleanup(setattr, ml, "run_measured", cp.run_measured)
        ml.render_pbrt(Args, "city.pbrt", 2, "/tmp/x/pbrt-2.exr")
        self.assertEqual(calls, [(["/opt/pbrt", "--spp", "48", "--seed", "2", "--outfile", "/tmp/x/pbrt-2.exr",
                                   "city.pbrt"], "/tmp/x/pbrt-2.exr.out")])
        self.assertEqual(cp.pbrt_cmd("p", "s.pbrt", 4, "o.exr"), ["p", "--spp", "4", "--outfile", "o.exr", "s.pbrt"])


if __name__ == "__main__":
    unittest.main()
