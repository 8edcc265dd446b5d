"""The predictor from Python: the same dict as `echoservo predict --json`; bad traces refused."""
import glob
import os
import unittest

import numpy as np

import echoservo
from common import DATA, cli, cli_json

NAMES = ("trace", "column", "reference")  # what names the input, not a figure


class Predict(unittest.TestCase):
    def test_realistic_trace_same_as_the_program(self):
        r = echoservo.realistic_trace("regular", seed=2, duration_s=30)
        py = echoservo.predict(r["t_s"], r["position_mm"], r["truth_mm"], truth_t_s=r["truth_t_s"],
                               latency_s=0.1)
        cl = cli_json("predict", "--realistic", "regular", "--seed", 2, "--truth", "truth", "--json")
        series = py.pop("series")
        for k in NAMES:
            py.pop(k), cl.pop(k)
        self.assertEqual(py, cl)
        # The series the figures come from: what shipped against the truth at each instant.
        err = series["shipped_mm"] - series["truth_mm"]
        self.assertEqual(len(err), py["scored"])
        self.assertAlmostEqual(float(np.sqrt(np.mean(err ** 2))), py["shipped"]["rms_mm"], places=12)
        self.assertTrue(np.all(np.diff(series["t_s"]) > 0))
        self.assertEqual(len(series["competitors"]), len(py["competitors"]))
        self.assertTrue(np.all((series["chosen"] >= 0) & (series["chosen"] < len(series["competitors"]))))
        # The heart rate: the class's rate within 5 % (issue 32's figure).
        self.assertIsNotNone(py["ekf"]["heart_rate_bpm"])

    def test_real_trace_same_as_the_program(self):
        path = sorted(glob.glob(os.path.join(DATA, "heart_motion", "*.csv")))[0]
        rc, out, _ = cli("predict", path, "--json")
        self.assertEqual(rc, 0)
        import json
        cl = json.loads(out)
        t, x = echoservo.read_motion_trace(path)
        py = echoservo.predict(t, x, column=cl["column"])
        py.pop("series")
        for k in NAMES:
            py.pop(k), cl.pop(k)
        self.assertEqual(py, cl)

    def test_bad_traces(self):
        t = np.arange(300) * 0.04
        x = np.sin(2 * np.pi * 1.2 * t)
        with self.assertRaisesRegex(ValueError, "position_mm: 299 values for 300 times"):
            echoservo.predict(t, x[:-1])
        bad = x.copy()
        bad[5] = np.nan
        with self.assertRaisesRegex(ValueError, "position_mm: element 5 is not finite"):
            echoservo.predict(t, bad)
        t2 = t.copy()
        t2[10] = t2[9]
        with self.assertRaisesRegex(ValueError, "t_s: not strictly increasing at element 10"):
            echoservo.predict(t2, x)
        with self.assertRaisesRegex(ValueError, "t_s: expected a 1-D array"):
            echoservo.predict(np.zeros((2, 2)), x)
        with self.assertRaisesRegex(ValueError, "t_s: expected real numbers"):
            echoservo.predict(np.array(["a", "b"]), x[:2])
        with self.assertRaisesRegex(ValueError, "--harmonics"):
            echoservo.predict(t, x, harmonics="many")
        # A column of a 2-D table (a strided view) is accepted and converted.
        table = np.stack([t, x], axis=1)
        r = echoservo.predict(table[:, 0], table[:, 1])
        self.assertEqual(r["measurements"], 300)
        # Too short for the predictor: its message, naming the trace.
        with self.assertRaisesRegex(ValueError, "position_mm: the trace spans"):
            echoservo.predict(t[:50], x[:50])

    def test_same_message_as_the_program(self):
        path = sorted(glob.glob(os.path.join(DATA, "heart_motion", "*.csv")))[0]
        rc, _, err = cli("predict", path, "--column", "no_such_column")
        self.assertNotEqual(rc, 0)
        with self.assertRaises(ValueError) as e:
            echoservo.read_motion_trace(path, "no_such_column")
        self.assertIn(str(e.exception), err)


if __name__ == "__main__":
    unittest.main()
