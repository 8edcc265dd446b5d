"""Shared set-up of the Python API tests: where the module, the program and the data are.

CTest runs these with PYTHONPATH=<build>/python, ECHOSERVO_CLI=<build>/bin/echoservo and
ECHOSERVO_DATA_DIR=<repo>/data (tests/python/CMakeLists.txt).
"""
import json
import os
import subprocess
import tempfile

import echoservo  # noqa: F401  (the module under test; fails loudly when not built)

CLI = os.environ.get("ECHOSERVO_CLI", "echoservo")
DATA = os.environ.get("ECHOSERVO_DATA_DIR", os.path.join(os.path.dirname(__file__), "../../data"))


def cli(*args):
    """Runs the echoservo program in a child process; (rc, stdout, stderr)."""
    p = subprocess.run([CLI, *map(str, args)], capture_output=True, text=True, timeout=600)
    return p.returncode, p.stdout, p.stderr


def cli_json(*args):
    rc, out, err = cli(*args)
    if rc != 0:
        raise AssertionError(f"echoservo {' '.join(map(str, args))}: rc {rc}: {err}")
    return json.loads(out)


def workdir():
    return tempfile.mkdtemp(prefix="echoservo_pytest_")


def without(d, keys):
    """A copy of a JSON dict without the keys that measure time (they differ run to run); a
    dotted metric name ("latency.p50_ms") goes with its first part."""
    if isinstance(d, dict):
        return {k: without(v, keys) for k, v in d.items() if k not in keys and k.split(".")[0] not in keys}
    if isinstance(d, list):
        return [without(v, keys) for v in d]
    return d


def assert_same(test, got, want, rel=1e-9, path="$"):
    """Equal JSON values, numbers within `rel` (relative; the lab's fits run Ceres on several
    threads, whose sums may differ in the last bits between two runs, in or out of process)."""
    if isinstance(want, dict):
        test.assertIsInstance(got, dict, path)
        test.assertEqual(sorted(got), sorted(want), path)
        for k in want:
            assert_same(test, got[k], want[k], rel, f"{path}.{k}")
    elif isinstance(want, list):
        test.assertIsInstance(got, list, path)
        test.assertEqual(len(got), len(want), path)
        for i, (g, w) in enumerate(zip(got, want)):
            assert_same(test, g, w, rel, f"{path}[{i}]")
    elif isinstance(want, float) and not isinstance(got, bool):
        test.assertIsInstance(got, (int, float), path)
        test.assertLessEqual(abs(got - want), rel * max(abs(want), abs(got), 1e-300), path)
    else:
        test.assertEqual(got, want, path)
