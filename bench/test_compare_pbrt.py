#!/usr/bin/python3
"""Tests of compare_pbrt.py's arithmetic and tables (run by CTest, label `tools`).

Runs with known CPU times and sizes, so every printed figure can be checked
against its definition rather than just produced."""
import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import compare_pbrt as cp  # noqa: E402


class FilmPixels(unittest.TestCase):
    def write(self, text):
        f = tempfile.NamedTemporaryFile("w", suffix=".pbrt", delete=False)
        f.write(text)
        f.close()
        self.addCleanup(os.unlink, f.name)
        return f.name

    def test_resolution_is_read_from_the_film(self):
        p = self.write('Film "rgb" "string filename" [ "a.exr" ]\n  "integer yresolution" [ 108 ] "integer xresolution" [192]\n')
        self.assertEqual(cp.film_pixels(p), 192 * 108)

    def test_pbrt_default_resolution_where_unset(self):
        self.assertEqual(cp.film_pixels(self.write('Film "rgb" "integer xresolution" 64\n')), 64 * 720)
        self.assertEqual(cp.film_pixels(self.write('WorldBegin\n')), 1280 * 720)

    def test_every_validation_scene_has_its_film_size(self):
        for s in cp.resolve_scenes([]):
            self.assertNotEqual(cp.film_pixels(s), 1280 * 720, s)


class Arithmetic(unittest.TestCase):
    def test_per_sample_cost_min_median_and_peak(self):
        runs = [cp.Run(4.0, 100, 2.5), cp.Run(2.0, 300, 1.5), cp.Run(3.0, 200, 2.0)]
        s = cp.Summary(runs, samples=1_000_000)
        self.assertAlmostEqual(s.cpu_min, 2.0)
        self.assertAlmostEqual(s.cpu_med, 3.0)
        self.assertAlmostEqual(s.us_per_sample_min, 2.0)
        self.assertAlmostEqual(s.us_per_sample_med, 3.0)
        self.assertEqual(s.peak_mib, 300)
        self.assertAlmostEqual(s.wall_med, 2.0)

    def test_ratio_is_theia_samples_per_cpu_second_over_pbrt(self):
        theia = cp.Summary([cp.Run(1.0, 1, 1), cp.Run(2.0, 1, 1)], samples=100)
        pbrt = cp.Summary([cp.Run(3.0, 1, 1), cp.Run(5.0, 1, 1)], samples=100)
        med, mn = cp.speed_ratio(pbrt, theia)
        self.assertAlmostEqual(med, 4.0 / 1.5)
        self.assertAlmostEqual(mn, 3.0)

    def test_tables_print_the_figures(self):
        theia = cp.Summary([cp.Run(1.5, 250.4, 1)], samples=1000)
        pbrt = cp.Summary([cp.Run(3.0, 40.6, 2)], samples=1000)
        row = cp.comparison_table([("s", 10, 100, theia, pbrt)])[2]
        self.assertEqual(row, "| s | 10 x 100 | 1500.000 / 1500.000 | 3000.000 / 3000.000 | 2.00 (2.00) | 250 | 41 |")
        one = cp.Summary([cp.Run(1.8, 1, 3.0)], samples=1)
        two = cp.Summary([cp.Run(2.0, 1, 2.0)], samples=1)
        row = cp.scaling_table([("s", {1: one, 2: two})], [1, 2])[2]
        self.assertEqual(row, "| s | 3.00 | 2.00 | 1.50x | 1.80 | 2.00 |")

    def test_paired_ratio_is_the_median_of_per_round_ratios(self):
        # Round 2's machine was slow for both: the ratio of medians (5 / 2 = 2.5)
        # is not what any round measured; the paired median is 2.0.
        pbrt = [cp.Run(2.0, 1, 1), cp.Run(4.0, 1, 1), cp.Run(10.0, 1, 1)]
        theia = [cp.Run(1.0, 1, 1), cp.Run(2.0, 1, 1), cp.Run(4.0, 1, 1)]
        self.assertAlmostEqual(cp.paired_ratio(pbrt, theia), 2.0)

    def test_builds_take_turns_at_going_first(self):
        builds = ["theia", "base"]
        self.assertEqual([cp.round_order(builds, k)[0] for k in range(4)], ["base", "theia", "base", "theia"])
        self.assertEqual(cp.round_order(["theia"], 1), ["theia"])

    def test_a_base_build_adds_its_columns(self):
        theia = cp.Summary([cp.Run(1.5, 250.4, 1)], samples=1000)
        pbrt = cp.Summary([cp.Run(3.0, 40.6, 2)], samples=1000)
        base = cp.Summary([cp.Run(2.0, 240.0, 1)], samples=1000)
        table = cp.comparison_table([("s", 10, 100, theia, pbrt, base)])
        self.assertEqual(table[0].count("|"), 10)
        self.assertEqual(table[2], "| s | 10 x 100 | 1500.000 / 1500.000 | 3000.000 / 3000.000 | 2.00 (2.00) "
                                   "| 250 | 41 | 1.50 | 1.333 |")


if __name__ == "__main__":
    unittest.main()
