#!/usr/bin/env python3
"""Converts the shared real motion recordings into echoservo's motion-trace CSV format.

A motion trace (docs/predictor.md) is a CSV with a header, a time column `t` in seconds
and position columns in mm. Usage, from the repository root:

    python3 scripts/convert_motion_data.py /work/shared/data data

* heart_motion/st_lstm_phantom.csv (no header, 750 rows x 12 columns POI_x..AP3_z, mm,
  no stated sampling rate): ASSUMED 20 Hz. The trace repeats every 16.79 samples, so
  20 Hz puts the phantom at 71.5 bpm, a resting human rate. Written as
  heart_motion/phantom_20hz.csv with t = row / 20.
* respiration/201205101522-UAC-1-N-138-6.csv (";"-separated, decimal commas, timestamp
  in ms, last row a 0;0;0;0;0 sentinel): the sentinel is dropped and the timestamp becomes
  t in s from the first row; columns x, y, z in mm. Written as respiration/UAC_138.csv.
* respiration/201205101519-LAC-1-T-222-6.csv and 201205181211-UCC-1-N-320-6.csv: the
  same format and conversion, written as respiration/LAC_222.csv and UCC_320.csv. A row
  whose timestamp is not after the previous row's is dropped and reported (UCC_320 has
  one: frame 18440 stamped 614.67 ms between 307233 and 307450 ms).
Only the Python standard library is used.
"""
import csv
import os
import sys

PHANTOM_RATE_HZ = 20.0
PHANTOM_COLUMNS = ["POI_x", "POI_y", "POI_z", "AP1_x", "AP1_y", "AP1_z",
                   "AP2_x", "AP2_y", "AP2_z", "AP3_x", "AP3_y", "AP3_z"]


def convert_phantom(src, dst):
    with open(src, newline="") as f:
        rows = [[float(v) for v in r] for r in csv.reader(f) if r]
    with open(dst, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["t"] + PHANTOM_COLUMNS)
        for i, r in enumerate(rows):
            if len(r) != len(PHANTOM_COLUMNS):
                sys.exit(f"{src}:{i + 1}: expected {len(PHANTOM_COLUMNS)} columns")
            w.writerow([f"{i / PHANTOM_RATE_HZ:.3f}"] + [f"{v:.6f}" for v in r])
    return len(rows)


def convert_respiration(src, dst):
    out = []
    with open(src, newline="") as f:
        reader = csv.reader(f, delimiter=";")
        next(reader)  # "Frame";"Timestamp";"x";"y";"z"
        for r in reader:
            if not r:
                continue
            vals = [float(v.replace(",", ".")) for v in r]
            if all(v == 0.0 for v in vals):  # end-of-recording sentinel
                continue
            if out and vals[1] <= out[-1][1]:  # a corrupt timestamp (UCC_320: one row)
                print(f"{src}: frame {vals[0]:g}: timestamp {vals[1]:g} ms is not after "
                      f"{out[-1][1]:g} ms; row dropped")
                continue
            out.append(vals)
    t0 = out[0][1]
    with open(dst, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["t", "x", "y", "z"])
        for vals in out:
            w.writerow([f"{(vals[1] - t0) / 1000.0:.3f}"] + [f"{v:g}" for v in vals[2:5]])
    return len(out)


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    shared, data = sys.argv[1], sys.argv[2]
    n = convert_phantom(os.path.join(shared, "heart_motion", "st_lstm_phantom.csv"),
                        os.path.join(data, "heart_motion", "phantom_20hz.csv"))
    print(f"heart_motion/phantom_20hz.csv: {n} samples")
    n = convert_respiration(os.path.join(shared, "respiration", "201205101522-UAC-1-N-138-6.csv"),
                            os.path.join(data, "respiration", "UAC_138.csv"))
    print(f"respiration/UAC_138.csv: {n} samples")
    for src, dst in (("201205101519-LAC-1-T-222-6.csv", "LAC_222.csv"),
                     ("201205181211-UCC-1-N-320-6.csv", "UCC_320.csv")):
        n = convert_respiration(os.path.join(shared, "respiration", src),
                                os.path.join(data, "respiration", dst))
        print(f"respiration/{dst}: {n} samples")


if __name__ == "__main__":
    main()
