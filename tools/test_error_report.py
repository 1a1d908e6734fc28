#!/usr/bin/python3
"""Tests of error_report.py's arithmetic and report (run by CTest, label `tools`).

Synthetic logs with known error curves: a power law relMSE = c / t is a
straight line in log-log, so interpolated times-to-error and efficiencies are
exact and the report's numbers can be checked, not just produced."""
import json
import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import error_report as er  # noqa: E402


def write_log(path, scene, label, seconds, rel_mse):
    its = [{"spp_total": 4 * 2 ** i, "render_seconds": t, "rel_mse": e}
           for i, (t, e) in enumerate(zip(seconds, rel_mse))]
    with open(path, "w") as f:
        json.dump({"scene": f"/x/{scene}/scene.pbrt", "label": label, "scheduler": {"iterations": its}}, f)


class TimeToError(unittest.TestCase):
    def test_power_law_is_interpolated_exactly(self):
        t = [0.5, 1.0, 2.0, 4.0, 8.0]
        curve = {"seconds": er.np.array(t), "rel_mse": er.np.array([0.1 / x for x in t])}
        for target in (0.1, 0.05, 0.03, 0.0125):
            self.assertAlmostEqual(er.time_to_error(curve, target), 0.1 / target, places=9)
        self.assertIsNone(er.time_to_error(curve, 0.001))  # never reached

    def test_targets_lie_where_every_curve_passes(self):
        a = {"rel_mse": er.np.array([1.0, 0.1, 0.01])}
        b = {"rel_mse": er.np.array([0.5, 0.05, 0.02])}
        targets = er.error_targets([a, b])
        self.assertAlmostEqual(max(targets), 0.5)
        self.assertAlmostEqual(min(targets), 0.02)


class Report(unittest.TestCase):
    def test_twice_as_fast_configuration_has_efficiency_two(self):
        with tempfile.TemporaryDirectory() as d:
            t = [0.5, 1.0, 2.0, 4.0]
            write_log(os.path.join(d, "a.json"), "box", "default", t, [0.1 / x for x in t])
            write_log(os.path.join(d, "b.json"), "box", "fast", t, [0.05 / x for x in t])
            curves = [er.load_curve(os.path.join(d, n)) for n in ("a.json", "b.json")]
            path = er.report(curves, "default", os.path.join(d, "out"))
            text = open(path).read()
            fast = next(line for line in text.splitlines() if line.startswith("| fast |"))
            cells = [c.strip() for c in fast.strip("|").split("|")]
            self.assertEqual(cells[-3:], ["2.00", "2.00", "2.00"])
            self.assertTrue(os.path.exists(os.path.join(d, "out", "box.png")))

    def test_log_without_reference_errors_is_refused(self):
        with tempfile.TemporaryDirectory() as d:
            p = os.path.join(d, "plain.json")
            with open(p, "w") as f:
                json.dump({"scheduler": {"iterations": [{"spp_total": 4}]}}, f)
            with self.assertRaises(SystemExit):
                er.load_curve(p)


class Seeds(unittest.TestCase):
    def test_bar_follows_the_issue(self):
        pbrt = (0.0359, 0.00066, 0.0122)
        self.assertEqual(er.bar(pbrt), (0.0718, 0.00198, 0.0322))
        # Block relMSE is floored at 5e-4.
        self.assertEqual(er.bar((0.001, 1e-5, 0.0))[1], 5e-4)
        ok = {"rel_mse": 0.07, "block_rel_mse": 0.0019, "channel_mean_deviation": 0.03}
        self.assertTrue(er.meets_bar(ok, pbrt))
        for key, bad in (("rel_mse", 0.072), ("block_rel_mse", 0.002), ("channel_mean_deviation", 0.033)):
            self.assertFalse(er.meets_bar(dict(ok, **{key: bad}), pbrt), key)

    def test_diff_output_is_parsed_and_tiles_skipped(self):
        text = "relMSE 0.25\nblock_relMSE 0.001\nworst 32x32 tiles (x0 y0 ...):\ntile 0 0 32 32 5.7 1 1 1\n"
        self.assertEqual(er.parse_diff(text), {"relMSE": 0.25, "block_relMSE": 0.001})

    def test_one_firefly_holds_its_share(self):
        r = er.np.full((4, 8, 3), 0.1)
        x = r.copy()
        x[2, 5] = 10.1  # one bright pixel, everything else exact
        (px, py), share = er.worst_pixel(x, r)
        self.assertEqual((px, py), (5, 2))
        self.assertAlmostEqual(share, 1.0)
        x[0, 0] = 0.1 + 10.0  # a second, equal firefly halves it
        self.assertAlmostEqual(er.worst_pixel(x, r)[1], 0.5)


class EqualTime(unittest.TestCase):
    """`equal-time`'s aggregation and table on synthetic rows (no rendering)."""

    def rows(self):
        rows = []
        for scene in ("box", "panel"):
            for config, scale in (("unguided", 1.0), ("guided", 0.25)):
                for budget in (2.0, 8.0):
                    for seed, x in enumerate((1.0, 3.0, 2.0)):  # median 2
                        rows.append({"scene": scene, "configuration": config, "budget": budget, "seed": seed,
                                     "rel_mse": scale * x / budget, "mape": 0.1 * x, "seconds_per_spp": 0.01 * x,
                                     "spp_min": 10 * x, "spp_max": 11 * x, "path_length": 3.0 + x,
                                     "leaves": 40.0 + x if config == "guided" else None,
                                     "guide_failure_rate": None, "seed_variance": 0.5,
                                     "verdict": ("on", "off", "on")[seed] if config == "guided" else None})
        return rows

    def test_median_over_seeds_per_scene_configuration_and_budget(self):
        groups = er.aggregate(self.rows())
        self.assertEqual(len(groups), 2 * 2 * 2)
        self.assertEqual([(g["scene"], g["configuration"], g["budget"]) for g in groups[:3]],
                         [("box", "unguided", 2.0), ("box", "unguided", 8.0), ("box", "guided", 2.0)])
        g = groups[2]
        self.assertEqual(g["seeds"], 3)
        self.assertAlmostEqual(g["rel_mse"], 0.25 * 2.0 / 2.0)
        self.assertAlmostEqual(g["mape"], 0.2)
        self.assertAlmostEqual(g["leaves"], 42.0)
        self.assertIsNone(groups[0]["leaves"])          # no seed has it
        self.assertIsNone(g["guide_failure_rate"])
        self.assertEqual(g["verdicts"], "on, off, on")  # seed by seed, not a median
        self.assertIsNone(groups[0]["verdicts"])

    def test_table_has_one_row_per_group_ratios_to_the_baseline_and_dashes_where_absent(self):
        lines = er.equal_time_table(er.aggregate(self.rows()), "unguided")
        self.assertEqual(len(lines), 2 + 8)
        header = [c.strip() for c in lines[0].strip("|").split("|")]
        self.assertEqual(len(header), 14)
        self.assertIn("relMSE / unguided", header)
        for line in lines[2:]:
            cells = [c.strip() for c in line.strip("|").split("|")]
            self.assertEqual(len(cells), len(header))
            row = dict(zip(header, cells))
            self.assertEqual(row["relMSE / unguided"], "0.250" if row["configuration"] == "guided" else "1.000")
            self.assertEqual(row["guide-draw failures"], "-")
            self.assertEqual(row["leaves"], "42" if row["configuration"] == "guided" else "-")
            self.assertEqual(row["spp (min-max)"], "20-22")
            self.assertEqual(row["auto verdicts"], "on, off, on" if row["configuration"] == "guided" else "-")

    def test_log_statistics_read_what_the_log_has(self):
        log = {"resolution": [10, 10], "rays": {"camera": 400}, "time": {"render": 2.0},
               "scheduler": {"spp_per_pixel": {"min": 3, "max": 5}}, "paths": {"average_length": 3.5},
               "guiding": {"spatial_leaves": 82, "sampling": {"guide_draw_failure_rate": 0.1}}}
        s = er.log_statistics(log)
        self.assertAlmostEqual(s["seconds_per_spp"], 0.5)  # 2 s over 4 spp
        self.assertEqual((s["spp_min"], s["spp_max"], s["leaves"]), (3, 5, 82))
        self.assertAlmostEqual(s["guide_failure_rate"], 0.1)
        self.assertIsNone(s["verdict"])
        self.assertEqual(er.log_statistics({"guiding": {"auto": {"verdict": "off"}}})["verdict"], "off")
        bare = er.log_statistics({"resolution": [10, 10]})
        self.assertTrue(all(v is None for v in bare.values()))

    def test_variance_across_seeds_and_configurations(self):
        a, b = er.np.zeros((2, 2, 3)), er.np.full((2, 2, 3), 2.0)
        self.assertAlmostEqual(er.seed_variance([a, b]), 2.0)  # (1 + 1) / (2 - 1)
        self.assertIsNone(er.seed_variance([a]))
        self.assertEqual(er.parse_configuration("auto=--guiding auto"), ("auto", ["--guiding", "auto"]))
        self.assertEqual(er.parse_configuration("unguided="), ("unguided", []))
        with self.assertRaises(SystemExit):
            er.parse_configuration("=--guiding")

    def test_each_configuration_renders_with_its_binary(self):
        configs = [("unguided", []), ("guided", ["--guiding"]), ("guided-new", ["--guiding"])]
        self.assertEqual(er.configuration_binaries(None, configs, "build/theia"),
                         {"unguided": "build/theia", "guided": "build/theia", "guided-new": "build/theia"})
        self.assertEqual(er.configuration_binaries(["guided-new=/tmp/new/theia"], configs, "build/theia"),
                         {"unguided": "build/theia", "guided": "build/theia", "guided-new": "/tmp/new/theia"})
        for bad in ["guided-new", "=/tmp/theia", "auto=/tmp/theia"]:
            with self.assertRaises(SystemExit):
                er.configuration_binaries([bad], configs, "build/theia")


if __name__ == "__main__":
    unittest.main()
