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


if __name__ == "__main__":
    unittest.main()
