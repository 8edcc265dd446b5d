"""Volumes and PLUS sequences from Python: arrays, files, views, refusals."""
import os
import unittest

import numpy as np

import echoservo
from common import DATA, cli_json, workdir


class VolumeArrays(unittest.TestCase):
    def test_array_round_trip_through_files(self):
        rng = np.random.default_rng(1)
        voxels = rng.integers(0, 256, size=(5, 6, 7), dtype=np.uint8)  # (nz, ny, nx)
        v = echoservo.Volume(voxels, spacing_mm=(0.5, 0.6, 0.7), origin_mm=(1, 2, 3))
        self.assertEqual(v.dims, (7, 6, 5))
        np.testing.assert_array_equal(v.voxels, voxels)
        # x fastest: voxel (i, j, k) is voxels[k, j, i], at origin + index * spacing.
        np.testing.assert_allclose(v.index_to_physical((2, 1, 3)), (1 + 1.0, 2 + 0.6, 3 + 2.1))
        self.assertAlmostEqual(v.sample(v.index_to_physical((2, 1, 3))), voxels[3, 1, 2], places=9)
        d = workdir()
        for name in ("v.mha", "v.vti", "v.mhd"):
            path = os.path.join(d, name)
            echoservo.write_volume(v, path)
            r = echoservo.read_volume(path)
            np.testing.assert_array_equal(r.voxels, voxels, err_msg=name)
            np.testing.assert_allclose(r.spacing_mm, (0.5, 0.6, 0.7), err_msg=name)
            np.testing.assert_allclose(r.origin_mm, (1, 2, 3), err_msg=name)
            info = cli_json("info", path, "--json")
            self.assertEqual(info["dims"], [7, 6, 5], name)

    def test_voxels_are_a_view_of_the_volume(self):
        v = echoservo.Volume(np.zeros((2, 2, 2), np.uint8))
        view = v.voxels
        view[1, 0, 1] = 200  # k = 1, j = 0, i = 1
        self.assertAlmostEqual(v.sample(v.index_to_physical((1, 0, 1))), 200, places=9)
        self.assertFalse(view.flags.owndata)
        del v  # the view keeps the volume alive
        self.assertEqual(int(view[1, 0, 1]), 200)

    def test_poses_and_time(self):
        v = echoservo.Volume(np.zeros((2, 2, 2), np.uint8))
        self.assertIsNone(v.image_to_probe)
        t = np.eye(4)
        t[:3, 3] = (1, 2, 3)
        v.image_to_probe = t
        np.testing.assert_allclose(v.image_to_probe, t)
        v.timestamp_s = 1.25
        self.assertEqual(v.timestamp_s, 1.25)
        bad = np.eye(4)
        bad[0, 0] = 2
        with self.assertRaisesRegex(ValueError, "image_to_probe: .*rotation"):
            v.image_to_probe = bad


class BadArrays(unittest.TestCase):
    def test_refusals_name_the_argument(self):
        cases = [
            (lambda: echoservo.Volume(np.zeros((2, 2, 2), np.float32)), "voxels: expected dtype uint8"),
            (lambda: echoservo.Volume(np.zeros((2, 2), np.uint8)), "voxels: expected 3 dimensions"),
            (lambda: echoservo.Volume(np.zeros((2, 3, 4), np.uint8).transpose()), "voxels: expected a C-contiguous"),
            (lambda: echoservo.Volume(np.zeros((2, 2, 2), np.uint8), spacing_mm=(1, np.nan, 1)),
             "spacing_mm: element 1 is not finite"),
            (lambda: echoservo.Volume(np.zeros((2, 2, 2), np.uint8), spacing_mm=(1, 1)), "spacing_mm: expected 3"),
            (lambda: echoservo.Volume(np.zeros((2, 2, 2), np.uint8), spacing_mm=(1, -1, 1)), "spacing"),
            (lambda: echoservo.Volume("not an array"), "voxels: expected dtype uint8"),
            (lambda: echoservo.read_volume("/nonexistent/x.mha"), "/nonexistent/x.mha"),
            (lambda: echoservo.read_volume(os.path.join(DATA, "plus", "LICENSE")), "LICENSE"),
        ]
        for call, message in cases:
            with self.assertRaisesRegex(ValueError, message):
                call()


class Sequences(unittest.TestCase):
    def test_real_plus_sequence(self):
        path = os.path.join(DATA, "plus", "SpinePhantomFreehand.igs.mha")
        s = echoservo.read_sequence(path)
        info = cli_json("info", path, "--json")
        self.assertEqual(len(s), info["frames"])
        nx, ny, nz = s.frame_dims
        self.assertEqual(s.pixels.shape, (len(s), nz, ny, nx))
        self.assertEqual(s.pixels.dtype, np.uint8)
        t = s.timestamps_s
        self.assertTrue(np.all(np.diff(t) > 0))
        poses = s.transforms("ProbeToTracker")
        self.assertEqual(poses.shape, (len(s), 4, 4))
        ok = ~np.isnan(poses[:, 0, 0])
        self.assertGreater(ok.sum(), 0)
        # Every valid pose is rigid.
        for p in poses[ok]:
            np.testing.assert_allclose(p[:3, :3] @ p[:3, :3].T, np.eye(3), atol=1e-4)
        self.assertIn("ProbeToTrackerTransform", s.field_names)
        v = s.volume(3)
        np.testing.assert_array_equal(v.voxels, s.pixels[3])
        self.assertAlmostEqual(v.timestamp_s, t[3])

    def test_write_sequence_round_trip(self):
        vols = []
        for i in range(3):
            v = echoservo.Volume(np.full((2, 3, 4), 10 * i, np.uint8), spacing_mm=(0.5, 0.5, 0.5))
            v.timestamp_s = 0.04 * i
            vols.append(v)
        path = os.path.join(workdir(), "s.igs.mha")
        echoservo.write_sequence(vols, path)
        s = echoservo.read_sequence(path)
        self.assertEqual(len(s), 3)
        np.testing.assert_allclose(s.timestamps_s, [0, 0.04, 0.08])
        self.assertEqual(int(s.pixels[2].max()), 20)
        # Edit the pixels in place (a view) and write the sequence with its fields.
        s.pixels[1] = 77
        path2 = os.path.join(workdir(), "edited.igs.mha")
        s.write(path2)
        e = echoservo.read_sequence(path2)
        self.assertEqual(int(e.pixels[1].min()), 77)
        self.assertEqual(e.frame_fields(2), s.frame_fields(2))
        with self.assertRaises(IndexError):
            s.volume(3)
        with self.assertRaisesRegex(ValueError, "volumes: at least one"):
            echoservo.write_sequence([], path)


class Help(unittest.TestCase):
    def test_every_function_and_property_has_help(self):
        import inspect
        missing = []
        for name in dir(echoservo):
            if name.startswith("__"):
                continue
            obj = getattr(echoservo, name)
            members = [(name, obj)]
            if inspect.isclass(obj):
                members += [(f"{name}.{a}", v) for a, v in vars(obj).items()
                            if not a.startswith("_") or a == "__init__"]
            for full, v in members:
                doc = getattr(v, "__doc__", None) or ""
                short = full.split(".")[-1]
                text = [l for l in doc.splitlines() if l.strip() and not l.startswith(short + "(")
                        and not l.startswith("Overloaded")]
                if not text:
                    missing.append(full)
        self.assertEqual(missing, [])


if __name__ == "__main__":
    unittest.main()
