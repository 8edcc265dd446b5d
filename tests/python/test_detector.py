"""The detector from Python: the same results as `echoservo detect`, against ground truth."""
import os
import unittest

import numpy as np

import echoservo
from common import cli, cli_json, workdir


def truth(seq, i, name):
    return np.array(seq.frame_fields(i)[name].split(), float)


class Detection(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.rec = os.path.join(workdir(), "scan.igs.mha")
        echoservo.run_command(["scanner", "--record", cls.rec, "--frames", "3", "--fov", "30,14,70",
                               "--seed", "2"])
        cls.seq = echoservo.read_sequence(cls.rec)

    def test_same_as_the_program_and_near_the_truth(self):
        frames = cli_json("detect", self.rec, "--json")["frames"]
        det = echoservo.Detector()
        self.assertEqual(len(frames), len(self.seq))
        for i, f in enumerate(frames):
            d = det.detect(self.seq.volume(i))
            self.assertTrue(d.found)
            self.assertEqual(f["found"], d.found)
            np.testing.assert_allclose(d.tip_mm, f["tip"], rtol=0, atol=1e-9)
            np.testing.assert_allclose(d.axis_direction, f["axis_direction"], rtol=0, atol=1e-12)
            np.testing.assert_allclose(d.target_mm, f["target"], rtol=0, atol=1e-9)
            self.assertAlmostEqual(d.confidence, f["confidence"], places=12)
            # Against the simulator's ground truth (image frame): the detector's measured
            # accuracy on these volumes is ~0.1-0.5 mm (docs/detector.md); 1.5 mm is two voxels.
            self.assertLess(np.linalg.norm(d.tip_mm - truth(self.seq, i, "CatheterTip")), 1.5)
            cos = abs(float(np.dot(d.axis_direction, truth(self.seq, i, "CatheterAxisDirection"))))
            self.assertGreater(cos, np.cos(np.radians(3)))

    def test_array_input_and_tracking(self):
        v = self.seq.volume(0)
        # An array has no ImageToProbe: the beams' apex (the probe frame's origin) is given,
        # as `detect --probe-apex` gives it for a file.
        apex_mm = np.linalg.inv(v.image_to_probe)[:3, 3]
        det = echoservo.Detector(probe_apex_mm=apex_mm)
        a = det.detect(v)
        # The same voxels as an array with the volume's geometry (identity direction here).
        np.testing.assert_allclose(v.direction, np.eye(3))
        b = det.detect(np.array(v.voxels), spacing_mm=v.spacing_mm, origin_mm=v.origin_mm)
        self.assertTrue(b.found)
        np.testing.assert_allclose(a.tip_mm, b.tip_mm, atol=1e-12)
        f = cli_json("detect", self.rec, "--json", "--probe-apex", ",".join(map(repr, apex_mm)))["frames"][0]
        np.testing.assert_allclose(b.tip_mm, f["tip"], atol=1e-9)
        det = echoservo.Detector()
        tracked = [det.track(self.seq.volume(i)) for i in range(len(self.seq))]
        self.assertFalse(tracked[0].tracked)
        self.assertTrue(all(t.tracked for t in tracked[1:]))
        frames = cli_json("detect", self.rec, "--json", "--track")["frames"]
        for t, f in zip(tracked, frames):
            np.testing.assert_allclose(t.tip_mm, f["tip"], atol=1e-9)

    def test_set_names_as_the_program(self):
        a = echoservo.Detector(set={"detector.sheath_diameter_mm": 1.6}).detect(self.seq.volume(0))
        b = echoservo.Detector(sheath_diameter_mm=1.6).detect(self.seq.volume(0))
        f = cli_json("detect", self.rec, "--json", "--set", "detector.sheath_diameter_mm=1.6")["frames"][0]
        np.testing.assert_allclose(a.axis_point_mm, f["axis_point"], atol=1e-9)
        np.testing.assert_allclose(b.axis_point_mm, f["axis_point"], atol=1e-9)

    def test_bad_settings_same_message_as_the_program(self):
        rc, _, err = cli("detect", self.rec, "--set", "detector.sheath_diameter_mm=50")
        self.assertNotEqual(rc, 0)
        with self.assertRaises(ValueError) as e:
            echoservo.Detector(set={"detector.sheath_diameter_mm": 50})
        self.assertIn(str(e.exception), err)
        with self.assertRaisesRegex(ValueError, "unknown parameter 'detector.sheath'"):
            echoservo.Detector(set={"detector.sheath": 1})
        with self.assertRaisesRegex(ValueError, "only .*an array"):
            echoservo.Detector().detect(self.seq.volume(0), spacing_mm=(1, 1, 1))
        with self.assertRaisesRegex(ValueError, "spacing_mm: required"):
            echoservo.Detector().detect(np.zeros((4, 4, 4), np.uint8))
        with self.assertRaisesRegex(ValueError, "give one"):
            echoservo.Detector(probe_apex_mm=(0, 0, 0), beam_direction=(0, 0, 1))

    def test_parameters_registry(self):
        names = {p["name"]: p for p in echoservo.parameters()}
        self.assertEqual(names["detector.sheath_diameter_mm"]["unit"], "mm")
        rc, out, _ = cli("tune", "params")
        self.assertEqual(rc, 0)
        self.assertEqual(len(names), sum(1 for line in out.splitlines() if "." in line.split(" ")[0]))


if __name__ == "__main__":
    unittest.main()
