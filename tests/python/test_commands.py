"""Commands run in the interpreter's process give it back as they found it: no locked memory
(the demo's real-time servo locks all of it), the interpreter's signal handlers."""
import os
import signal
import unittest

import echoservo
from common import workdir


def locked_kb():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmLck:"):
                return int(line.split()[1])
    return -1


class Commands(unittest.TestCase):
    def test_demo_leaves_no_locked_memory_and_the_handlers(self):
        self.assertEqual(locked_kb(), 0)
        handler = signal.getsignal(signal.SIGINT)
        echoservo.run_command(["demo", "--duration", "1", "--seed", "2", "--out",
                               os.path.join(workdir(), "run")])
        self.assertEqual(locked_kb(), 0)
        self.assertIs(signal.getsignal(signal.SIGINT), handler)

    def test_help_and_parse_errors(self):
        self.assertIn("Usage", echoservo.run_command(["detect", "--help"]))
        with self.assertRaisesRegex(ValueError, "FILE is required"):
            echoservo.run_command(["detect"])
        with self.assertRaisesRegex(ValueError, "subcommand is required"):  # as the program says
            echoservo.run_command(["nosuchcommand"])


if __name__ == "__main__":
    unittest.main()
