"""Every function of the module on wrong arguments: an exception naming what is wrong, never a
crash of the interpreter."""
import os
import unittest

import numpy as np

import echoservo
from common import workdir

GARBAGE = [None, "", "x", -1, 1e308, float("nan"), [], {}, np.zeros(0), np.zeros((2, 2, 2)),
           np.full(3, np.nan), object()]


class BadInput(unittest.TestCase):
    def test_functions_refuse_garbage(self):
        d = workdir()
        missing = os.path.join(d, "missing")
        calls = {
            "read_volume": lambda g: echoservo.read_volume(g),
            "write_volume": lambda g: echoservo.write_volume(g, os.path.join(d, "v.mha")),
            "read_sequence": lambda g: echoservo.read_sequence(g),
            "write_sequence": lambda g: echoservo.write_sequence(g, os.path.join(d, "s.igs.mha")),
            "Volume": lambda g: echoservo.Volume(g),
            "Volume spacing": lambda g: echoservo.Volume(np.zeros((2, 2, 2), np.uint8), spacing_mm=g),
            "Detector set": lambda g: echoservo.Detector(set=g),
            "Detector apex": lambda g: echoservo.Detector(probe_apex_mm=g),
            "detect": lambda g: echoservo.Detector().detect(g),
            "predict t": lambda g: echoservo.predict(g, np.zeros(10)),
            "predict x": lambda g: echoservo.predict(np.arange(10.0), g),
            "read_motion_trace": lambda g: echoservo.read_motion_trace(g),
            "read_run": lambda g: echoservo.read_run(g),
            "read_em_log": lambda g: echoservo.read_em_log(g),
            "report": lambda g: echoservo.report(g),
            "read_trial": lambda g: echoservo.read_trial(g),
            "read_dataset": lambda g: echoservo.read_dataset(g),
            "lab_compare": lambda g: echoservo.lab_compare(g),
            "lab_diagnose": lambda g: echoservo.lab_diagnose(g),
            "tune_trial": lambda g: echoservo.tune_trial(g),
            "tune_report": lambda g: echoservo.tune_report(g),
            "run_command": lambda g: echoservo.run_command(g),
            "realistic_trace": lambda g: echoservo.realistic_trace(g),
            "IgtlClient": lambda g: echoservo.IgtlClient(g, g),
        }
        valid = {"Detector set": ({},), "Detector apex": (None,)}  # the defaults
        for name, call in calls.items():
            for g in GARBAGE + [missing]:
                if any(g is v or (isinstance(g, dict) and g == v) for v in valid.get(name, ())):
                    continue
                with self.subTest(name=name, arg=repr(g)[:40]):
                    with self.assertRaises((ValueError, TypeError, RuntimeError, IndexError)) as e:
                        call(g)
                    self.assertTrue(str(e.exception).strip(), "an empty message")

    def test_messages_name_the_file(self):
        missing = os.path.join(workdir(), "nothing_here.mha")
        for f in (echoservo.read_volume, echoservo.read_sequence, echoservo.read_trial,
                  echoservo.read_run, echoservo.read_em_log):
            with self.assertRaises(ValueError) as e:
                f(missing)
            self.assertIn("nothing_here", str(e.exception), f.__name__)


if __name__ == "__main__":
    unittest.main()
