"""The model lab from Python on data from the independent generator (scripts/open_world2,
which shares no code with echoservo): the same verdict and figures as the program, and the
learnt shape, as arrays, against the generator's hidden law."""
import json
import os
import subprocess
import sys
import unittest

import numpy as np

import echoservo
from common import assert_same, cli, cli_json, without, workdir

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")


def as_lists(d):
    if isinstance(d, dict):
        return {k: as_lists(v) for k, v in d.items()}
    if isinstance(d, list):
        return [as_lists(v) for v in d]
    if isinstance(d, np.ndarray):
        return d.tolist()
    return d


class OpenWorldRipple(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.work = workdir()
        subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "open_world2", "generate.py"),
                        "--out", cls.work, "--case", "ripple_friction"], check=True,
                       capture_output=True)
        cls.data = os.path.join(cls.work, "ripple_friction")
        with open(os.path.join(cls.data, "truth.json")) as f:
            cls.truth = json.load(f)["parameters"]["ripple_friction"]
        cls.diagnosis = echoservo.lab_diagnose(cls.data, "--model", "seed",
                                               "--propose-dir", os.path.join(cls.work, "py_proposal"))

    def test_same_as_the_program(self):
        cl = cli_json("lab", "diagnose", self.data, "--model", "seed", "--json",
                      "--propose-dir", os.path.join(self.work, "cli_proposal"))
        got = as_lists(self.diagnosis)
        # The proposal's files are where each run wrote them.
        for d in (got, cl):
            if d.get("proposal"):
                d["proposal"].pop("spec", None)
                d["proposal"].pop("file", None)
        assert_same(self, without(got, ("fit_seconds", "seconds")), without(cl, ("fit_seconds", "seconds")))

    def test_learnt_shape_is_the_hidden_law(self):
        shapes = self.diagnosis["learning"]["shapes"]
        friction = [s for s in shapes if s["variables"] == ["base_mm"] and s["unit"] == "N"]
        self.assertTrue(friction, [s["words"] for s in shapes])
        s = friction[0]
        knots, values = s["knots"][0], s["values"]
        self.assertIsInstance(values, np.ndarray)
        self.assertEqual(values.dtype, np.float64)
        self.assertEqual(knots.shape, values.shape)
        t = self.truth
        hidden = t["a_n"] * (1 + np.sin(2 * np.pi * knots / t["period_mm"] + t["phase_rad"])) / 2
        # Up to a constant (the seed's Coulomb friction takes the mean): the shape's error is
        # below the force sensor's noise (0.0075 N) and it swings as far as the hidden law.
        diff = (values - values.mean()) - (hidden - hidden.mean())
        noise_n = self.diagnosis["noise"]["force_n"]
        self.assertLess(float(np.sqrt(np.mean(diff ** 2))), noise_n)
        self.assertLess(abs(np.ptp(values) - t["a_n"]), 0.15 * t["a_n"])


class Simulate(unittest.TestCase):
    def test_simulate_trials_and_read_back(self):
        out = os.path.join(workdir(), "sim")
        trials = echoservo.simulate_trials("seed+capstan_friction", out, configs="seed",
                                           trajectories="sine:4:0.8", duration_s=2, args=["--seed", "3"])
        self.assertEqual(len(trials), 1)
        t = trials[0]
        self.assertEqual(len(t["t_s"]), len(t["force_n"]))
        self.assertAlmostEqual(float(np.median(np.diff(t["t_s"]))), 0.001, places=9)  # 1 kHz
        # The base follows the 4 mm sine (amplitude within its backlash and lag).
        self.assertGreater(np.ptp(t["base_mm"]), 6.0)
        with self.assertRaisesRegex(ValueError, "no_such_effect"):
            echoservo.simulate_trials("seed+no_such_effect", out)
        rc, _, err = cli("sim", "record", "--out", out, "--effects", "seed+no_such_effect")
        self.assertNotEqual(rc, 0)
        with self.assertRaises(ValueError) as e:
            echoservo.simulate("record", "--out", out, "--effects", "seed+no_such_effect")
        # The same message up to the list of known effects, which in this interpreter also
        # holds any plugin's loaded earlier (a plugin stays loaded for the session).
        self.assertIn(str(e.exception).split(" (known:")[0], err)


class Plugins(unittest.TestCase):
    def test_an_effect_plugin_loads_in_the_interpreter(self):
        # A plugin calls the hw code of whoever loads it: here the module (its symbols global).
        plugin = os.environ["ECHOSERVO_EXAMPLE_PLUGIN"]
        listing = echoservo.simulate("effects", "--plugin", plugin)
        rc, out, _ = cli("sim", "effects", "--plugin", plugin)
        self.assertEqual(rc, 0)
        self.assertEqual(listing, out)
        self.assertIn("quadratic drag", listing)


if __name__ == "__main__":
    unittest.main()
