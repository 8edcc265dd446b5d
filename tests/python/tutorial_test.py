"""Runs docs/python.md's tutorial (every Python block, in order, in one namespace) and checks
what the page says of the results, and that the notebook holds the same cells; the lab loop's
verdicts and figures are those of the program on the same data."""
import os
import sys
import unittest

import numpy as np

from common import assert_same, cli_json, without

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import python_notebook  # noqa: E402

TIMING = ("fit_seconds", "seconds", "time_ms")


class Tutorial(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        with open(python_notebook.PAGE, encoding="utf-8") as f:
            cls.cells = python_notebook.tutorial_cells(f.read())
        cls.ns = {"__name__": "tutorial"}
        for kind, source in cls.cells:
            if kind == "code":
                exec(compile(source, "docs/python.md", "exec"), cls.ns)

    def test_notebook_holds_the_page(self):
        import json
        with open(python_notebook.NOTEBOOK, encoding="utf-8") as f:
            nb = json.load(f)
        code = ["".join(c["source"]) for c in nb["cells"] if c["cell_type"] == "code"]
        self.assertEqual(code, [s for k, s in self.cells if k == "code"])
        self.assertEqual(python_notebook.text(nb), python_notebook.text(python_notebook.notebook(self.cells)))
        # A notebook Jupyter opens: nbformat's own schema check (cell ids included).
        import nbformat
        nbformat.validate(nbformat.reads(python_notebook.text(nb), as_version=4))

    def test_lab_loop_claims(self):
        ns = self.ns
        self.assertEqual(len(ns["trials"]), 16)
        seed, fixed = ns["seed_fit"], ns["fixed_fit"]
        noise = seed["noise"]
        # Tip error at the sensor's noise level, force error far above the force noise.
        self.assertLess(seed["rms_mm"], 1.5 * noise["tip_mm"])
        self.assertGreater(seed["force_rms_n"], 5 * noise["force_n"])
        # The residual files' columns are what the figures come from: their RMS over every
        # sample is the fit's tip and force RMS.
        fitted = ns["fitted"]
        force = np.concatenate([t["force_n"] - t["extra"]["force_model"] for t in fitted])
        tip = np.concatenate([t["tip_mm"] - t["extra"]["tip_model"] for t in fitted])
        self.assertAlmostEqual(float(np.sqrt(np.mean(force ** 2))) / seed["force_rms_n"], 1, places=9)
        self.assertAlmostEqual(float(np.sqrt(np.mean(tip ** 2))) / seed["rms_mm"], 1, places=9)
        # The missed friction grows with the bend: rank correlation, and its sign at the ends.
        bend, excess = ns["bend_deg"], ns["excess_n"]
        ranks = lambda a: np.argsort(np.argsort(a))
        rho = np.corrcoef(ranks(bend), ranks(excess))[0, 1]
        self.assertGreater(rho, 0.8)
        self.assertLess(excess[np.argmin(bend)], 0)
        self.assertGreater(excess[np.argmax(bend)], 0)
        d = ns["diagnosis"]
        self.assertEqual(d["verdict"], "missing_effect")
        self.assertEqual(ns["best"]["effect"], "capstan_friction")
        self.assertGreater(ns["best"]["force_explained"], 0.9)
        self.assertLess(fixed["force_rms_n"], 0.1 * seed["force_rms_n"])
        self.assertEqual(ns["check"]["verdict"], "adequate")
        # The uncatalogued tight spot: unexplained, its law recovered, the error at the noise.
        self.assertEqual(ns["unknown"]["verdict"], "unexplained")
        for got, hidden in ((ns["peak_n"], 0.4), (ns["where_mm"], 3.0), (ns["width_mm"], 1.5)):
            self.assertLess(abs(got - hidden), 0.02 * hidden)
        self.assertLess(ns["with_proposal"]["force_rms_n"], 1.2 * ns["unknown"]["noise"]["force_n"])
        for name in ("missed_friction.png", "tight_spot.png", "detection.png", "run_error.png"):
            self.assertGreater(os.path.getsize(os.path.join(ns["work"], name)), 1000, name)

    def test_lab_loop_same_as_the_program(self):
        bench = self.ns["bench"]
        for got, args in [
            (self.ns["diagnosis"], ("lab", "diagnose", bench, "--model", "seed", "--json")),
            (self.ns["fixed_fit"], ("lab", "compare", bench, "--model", "seed+capstan_friction", "--json")),
            (self.ns["check"], ("lab", "diagnose", bench, "--model", "seed+capstan_friction", "--json")),
        ]:
            assert_same(self, without(got, TIMING), without(cli_json(*args), TIMING))

    def test_detection_claims(self):
        ns = self.ns
        self.assertTrue(ns["det"].found)
        err = np.linalg.norm(ns["det"].tip_mm - ns["tip_true_mm"])
        self.assertLess(err, float(np.max(ns["vol"].spacing_mm)))

    def test_run_claims(self):
        ns = self.ns
        acc, series = ns["acc"], ns["series"]
        self.assertAlmostEqual(float(np.sqrt(np.mean(series["error_mm"] ** 2))),
                               acc["tip_to_target_rms_mm"], places=9)
        cl = cli_json("report", ns["run"], "--json", "--out", os.path.join(ns["work"], "report.html"))
        assert_same(self, without({k: v for k, v in acc.items() if k != "series"}, TIMING),
                    without(cl, TIMING))
        # The closed loop follows the target: the seed's water-tank result is 0.86 mm RMS.
        self.assertLess(acc["tip_to_target_rms_mm"], 1.5)

    def test_predictor_claims(self):
        pred = self.ns["pred"]
        self.assertLess(pred["shipped"]["rms_mm"], pred["baselines"]["zero_order_hold"]["rms_mm"])
        self.assertIsNotNone(pred["ekf"]["heart_rate_bpm"])
        s = pred["series"]
        self.assertAlmostEqual(float(np.sqrt(np.mean((s["shipped_mm"] - s["truth_mm"]) ** 2))),
                               pred["shipped"]["rms_mm"], places=12)
        self.assertGreater(os.path.getsize(os.path.join(self.ns["work"], "prediction.png")), 1000)

    def test_run_files(self):
        import echoservo
        from common import cli
        run = self.ns["run"]
        r = echoservo.read_run(run)
        with open(os.path.join(run, "targets.csv")) as f:
            rows = sum(1 for line in f if line.strip()) - 1
        self.assertEqual(len(r["targets"]["acquired_s"]), rows)
        self.assertEqual(r["targets"]["target_mm"].shape, (rows, 3))
        self.assertTrue(np.all(np.diff(r["targets"]["acquired_s"]) > 0))
        em = echoservo.read_em_log(os.path.join(run, "em.csv"))
        self.assertEqual(em["position_mm"].shape, (len(em["t_s"]), 3))
        self.assertGreater(int(em["valid"].sum()), 0.9 * len(em["t_s"]))
        # A bad RUN: the program's message.
        missing = os.path.join(self.ns["work"], "no_such_run")
        rc, _, err = cli("report", missing, "--out", os.path.join(self.ns["work"], "x.html"))
        self.assertNotEqual(rc, 0)
        with self.assertRaises(ValueError) as e:
            echoservo.report(missing)
        self.assertIn(str(e.exception), err)


if __name__ == "__main__":
    unittest.main()
