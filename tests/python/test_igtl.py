"""The OpenIGTLink client from Python against `echoservo scanner` serving simulated volumes."""
import socket
import subprocess
import unittest

import numpy as np

import echoservo
from common import CLI


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Igtl(unittest.TestCase):
    def test_receives_the_served_volumes(self):
        port = free_port()
        server = subprocess.Popen([CLI, "scanner", "--port", str(port), "--bind", "127.0.0.1",
                                   "--frames", "4", "--min-clients", "1", "--rate", "10",
                                   "--fov", "30,14,70", "--seed", "1"],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            frames = []
            with echoservo.IgtlClient("127.0.0.1", port, max_connect_failures=50) as client:
                while len(frames) < 4:
                    f = client.next(timeout_s=20)
                    self.assertIsNotNone(f, client.stats())
                    frames.append(f)
                stats = client.stats()
            self.assertEqual(stats["frames"], 4)
            self.assertEqual(stats["rejected"], 0)
            times = [f["volume"].timestamp_s for f in frames]
            self.assertTrue(np.all(np.diff(times) > 0))
            det = echoservo.Detector()
            for f in frames:
                v = f["volume"]
                self.assertEqual(v.voxels.dtype, np.uint8)
                self.assertEqual(v.dims, (48, 41, 121))  # the 30 x 14 deg x 70 mm field of view
                self.assertTrue(det.detect(v).found)
        finally:
            out, err = server.communicate(timeout=60)
        # The stream ended, and the server saw one client.
        self.assertEqual(server.returncode, 0, err)
        self.assertIn("sent 4 frames to 1 client", out)

    def test_bad_arguments_and_no_server(self):
        with self.assertRaisesRegex(ValueError, "port: expected 1-65535"):
            echoservo.IgtlClient("127.0.0.1", 0)
        with self.assertRaisesRegex(ValueError, "timeout_s"):
            echoservo.IgtlClient("127.0.0.1", 1).next(timeout_s=-1)
        c = echoservo.IgtlClient("127.0.0.1", free_port(), max_connect_failures=2)
        c.start()
        self.assertIsNone(c.next(timeout_s=3))
        self.assertTrue(c.ended)
        self.assertGreaterEqual(c.stats()["connect_failures"], 2)
        c.stop()


if __name__ == "__main__":
    unittest.main()
