#!/usr/bin/env python3
"""Python API speed: reading the simulated scanner's 4.9 MB volume (160 x 148 x 208 uint8,
an uncompressed .mha) into numpy and running the detector from Python, against the same
calls made by C++ in the same process (echoservo._cpp_read_and_detect). Alternating blocks
(C++, Python, C++, ...), medians; the ratio Python/C++ is the figure (docs/python.md,
docs/benchmarks.md).

Usage: PYTHONPATH=build/python /usr/bin/python3 bench/python_detect_bench.py [--reps N] [--blocks B]
"""
import argparse
import os
import statistics
import tempfile
import time

import numpy as np

import echoservo


def python_read_and_detect(path, detector):
    t0 = time.perf_counter()
    v = echoservo.read_volume(path)
    voxels = v.voxels  # the numpy array (a view)
    d = detector.detect(v)
    t1 = time.perf_counter()
    return t1 - t0, voxels.nbytes, d


def python_array_detect(voxels, spacing, origin, apex, detector):
    t0 = time.perf_counter()
    d = detector.detect(voxels, spacing_mm=spacing, origin_mm=origin)
    return time.perf_counter() - t0, d


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--reps", type=int, default=5, help="calls per block")
    ap.add_argument("--blocks", type=int, default=6, help="blocks per side, alternating")
    a = ap.parse_args()
    work = tempfile.mkdtemp(prefix="echoservo_pybench_")
    rec = os.path.join(work, "one.igs.mha")
    echoservo.run_command(["scanner", "--record", rec, "--frames", "1", "--seed", "1"])
    vol = echoservo.read_sequence(rec).volume(0)
    path = os.path.join(work, "volume.mha")
    echoservo.write_volume(vol, path, compress=False)
    size_mb = os.path.getsize(path) / 1e6
    det = echoservo.Detector()
    apex = np.linalg.inv(vol.image_to_probe)[:3, 3]
    det_apex = echoservo.Detector(probe_apex_mm=apex)
    voxels = np.array(vol.voxels)
    cpp, py, arr = [], [], []
    echoservo._cpp_read_and_detect(path, 1)  # warm the page cache and the allocator
    for _ in range(a.blocks):
        cpp += echoservo._cpp_read_and_detect(path, a.reps)
        for _ in range(a.reps):
            s, nbytes, d = python_read_and_detect(path, det)
            py.append(s)
        for _ in range(a.reps):
            s, d2 = python_array_detect(voxels, vol.spacing_mm, vol.origin_mm, apex, det_apex)
            arr.append(s)
    m_cpp, m_py, m_arr = (statistics.median(x) for x in (cpp, py, arr))
    print(f"volume {vol.dims[0]}x{vol.dims[1]}x{vol.dims[2]} uint8, file {size_mb:.2f} MB "
          f"(numpy array {nbytes / 1e6:.2f} MB); found {d.found}, {len(cpp)} calls a side")
    print(f"C++ read_volume + detect:            median {1e3 * m_cpp:8.2f} ms")
    print(f"Python read_volume + voxels + detect: median {1e3 * m_py:8.2f} ms  ratio {m_py / m_cpp:.3f}")
    print(f"Python detect(numpy array, copied):   median {1e3 * m_arr:8.2f} ms  "
          f"(no file read; ratio to C++ read + detect {m_arr / m_cpp:.3f})")


if __name__ == "__main__":
    main()
