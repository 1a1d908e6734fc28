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


if __name__ == "__main__":
    unittest.main()
