"""Tuning from Python: parameters by name, one trial, a study and its report — the same
figures as the program."""
import json
import os
import unittest

import echoservo
from common import assert_same, cli, cli_json, without, workdir

# What measures time (it differs between two runs): a trial's stage times and the replay's
# latency, a study's durations.
TIMING = ("load_s", "replay_s", "score_s", "latency", "seconds", "elapsed_s", "wall_s", "started",
          "finished")


class Tune(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.work = workdir()
        cls.rec_dir = os.path.join(cls.work, "rec")
        os.makedirs(cls.rec_dir)
        cls.recs = []
        for seed in (1, 2):
            r = os.path.join(cls.rec_dir, f"late{seed}.igs.mha")
            echoservo.run_command(["scanner", "--record", r, "--frames", "80", "--rate", "10",
                                   "--fov", "30,14,70", "--target-motion", "mitral:72:10",
                                   "--stamp-delay", "0.1", "--seed", str(seed)])
            cls.recs.append(r)

    def test_trial_same_as_the_program(self):
        args = ["--recording", self.recs[0], "--set", "scanner.stamp_delay_s=0.1"]
        py = echoservo.tune_trial(*args)
        cl = cli_json("tune", "trial", *args, "--json")
        assert_same(self, without(py, TIMING), without(cl, TIMING))
        self.assertIn("prediction.truth_rms_mm", py["metrics"])

    def test_study_and_report(self):
        spec = os.path.join(self.work, "stamp.json")
        with open(spec, "w") as f:
            json.dump({"description": "stamp delay", "recordings": [self.rec_dir + "/"],
                       "scoring": {"metric": "prediction.truth_rms_mm", "latency_s": 0.1, "from_s": 1.0},
                       "parameters": {"scanner.stamp_delay_s": {"values": [0.1]}},
                       "search": {"method": "grid"}}, f)
        study = os.path.join(self.work, "study")
        report = echoservo.tune_study(spec, study, "--jobs", "2")
        cl = cli_json("tune", "report", study, "--json")
        assert_same(self, without(report, TIMING), without(cl, TIMING))
        self.assertEqual(echoservo.tune_report(study), report)

    def test_bad_parameter_same_message(self):
        rc, _, err = cli("tune", "trial", "--recording", self.recs[0], "--set", "detector.no_such=1")
        self.assertNotEqual(rc, 0)
        with self.assertRaises(ValueError) as e:
            echoservo.tune_trial("--recording", self.recs[0], "--set", "detector.no_such=1")
        self.assertIn(str(e.exception), err)
        self.assertIn("detector.no_such", str(e.exception))


if __name__ == "__main__":
    unittest.main()
