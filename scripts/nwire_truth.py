#!/usr/bin/env python3
"""Ground truth for the wires in a reconstructed N-wire volume, and the detector's error.

Standard library only (no numpy). Reads a MetaImage volume (.mha, uint8, raw or zlib; as
`echoservo reconstruct` writes it) and finds each wire's echo:

1. threshold: voxels brighter than --threshold (default: the 99.7th percentile of the
   non-zero voxels);
2. connected components (26-neighbourhood) of those voxels; components with at least
   --min-voxels voxels whose principal axis is at least --min-length-mm long and whose
   thickness (RMS distance from that axis) is under --max-rms-mm are wire candidates;
3. each candidate is refined by an intensity-weighted least-squares line: all voxels
   within --radius-mm of the current line and brighter than the local background
   (--floor, default half the threshold) weigh (value - floor); the line is the weighted
   centroid and the principal eigenvector of the weighted scatter; three passes.

Output (JSON on stdout): per wire the centre (mm, volume frame), unit direction, length
along the axis (mm), RMS perpendicular distance (mm) and voxel count. With --detect FILE
(the JSON of `echoservo detect VOLUME --json`), the detected axis's angle to each wire
(degrees, 0..90) and the distance from each wire's centre to the detected axis line (mm),
and the distance between the two lines (mm; the skew-line distance).

Usage:
  python3 scripts/nwire_truth.py runs/nwire.mha [--detect det.json]
"""

import argparse
import json
import math
import random
import struct
import sys
import zlib


def read_mha(path):
    with open(path, "rb") as f:
        data = f.read()
    header = {}
    pos = 0
    while True:
        end = data.index(b"\n", pos)
        line = data[pos:end].decode("latin-1").strip()
        pos = end + 1
        if "=" in line:
            key, value = line.split("=", 1)
            header[key.strip()] = value.strip()
            if key.strip() == "ElementDataFile":
                break
    if header.get("ElementDataFile") != "LOCAL":
        raise SystemExit(f"{path}: only ElementDataFile = LOCAL is supported")
    if header.get("ElementType") != "MET_UCHAR":
        raise SystemExit(f"{path}: only MET_UCHAR is supported")
    dims = [int(v) for v in header["DimSize"].split()]
    spacing = [float(v) for v in header.get("ElementSpacing", "1 1 1").split()]
    origin = [float(v) for v in header.get("Offset", "0 0 0").split()]
    matrix = [float(v) for v in header.get("TransformMatrix", "1 0 0 0 1 0 0 0 1").split()]
    if matrix != [1, 0, 0, 0, 1, 0, 0, 0, 1]:
        raise SystemExit(f"{path}: only an identity TransformMatrix is supported")
    raw = data[pos:]
    if header.get("CompressedData", "False").lower() == "true":
        raw = zlib.decompress(raw)
    n = dims[0] * dims[1] * dims[2]
    if len(raw) < n:
        raise SystemExit(f"{path}: {len(raw)} bytes of pixels, {n} expected")
    return dims, spacing, origin, raw[:n]


def sym_eig(a):
    """Eigen-decomposition of a symmetric 3x3 (Jacobi). Returns (values, vectors as columns)
    sorted by decreasing value."""
    a = [row[:] for row in a]
    v = [[1.0 if i == j else 0.0 for j in range(3)] for i in range(3)]
    for _ in range(50):
        off = max(abs(a[0][1]), abs(a[0][2]), abs(a[1][2]))
        if off < 1e-14:
            break
        for p, q in ((0, 1), (0, 2), (1, 2)):
            if abs(a[p][q]) < 1e-300:
                continue
            theta = (a[q][q] - a[p][p]) / (2 * a[p][q])
            t = (1.0 if theta >= 0 else -1.0) / (abs(theta) + math.sqrt(theta * theta + 1))
            c = 1 / math.sqrt(t * t + 1)
            s = t * c
            for k in range(3):
                akp, akq = a[k][p], a[k][q]
                a[k][p] = c * akp - s * akq
                a[k][q] = s * akp + c * akq
            for k in range(3):
                apk, aqk = a[p][k], a[q][k]
                a[p][k] = c * apk - s * aqk
                a[q][k] = s * apk + c * aqk
            for k in range(3):
                vkp, vkq = v[k][p], v[k][q]
                v[k][p] = c * vkp - s * vkq
                v[k][q] = s * vkp + c * vkq
    vals = [a[i][i] for i in range(3)]
    order = sorted(range(3), key=lambda i: -vals[i])
    return [vals[i] for i in order], [[v[k][i] for k in range(3)] for i in order]


def weighted_line(points, weights):
    """Weighted centroid and principal direction, with the scatter's eigenvalues."""
    wsum = sum(weights)
    c = [sum(w * p[k] for p, w in zip(points, weights)) / wsum for k in range(3)]
    cov = [[0.0] * 3 for _ in range(3)]
    for p, w in zip(points, weights):
        d = [p[k] - c[k] for k in range(3)]
        for i in range(3):
            for j in range(3):
                cov[i][j] += w * d[i] * d[j]
    cov = [[x / wsum for x in row] for row in cov]
    vals, vecs = sym_eig(cov)
    d = vecs[0]
    norm = math.sqrt(sum(x * x for x in d))
    d = [x / norm for x in d]
    # A fixed sign convention: the largest component positive.
    k = max(range(3), key=lambda i: abs(d[i]))
    if d[k] < 0:
        d = [-x for x in d]
    return c, d, vals


def perp_dist(p, c, d):
    v = [p[k] - c[k] for k in range(3)]
    t = sum(v[k] * d[k] for k in range(3))
    return math.sqrt(max(0.0, sum(x * x for x in v) - t * t)), t


def find_wires(dims, spacing, origin, vox, args):
    nx, ny, nz = dims
    nonzero = sorted(b for b in vox if b > 0)
    if not nonzero:
        raise SystemExit("the volume is empty")
    thr = args.threshold
    if thr is None:
        thr = nonzero[min(len(nonzero) - 1, int(0.95 * len(nonzero)))]
    floor = args.floor if args.floor is not None else thr / 2

    def phys(x, y, z):
        return [origin[0] + x * spacing[0], origin[1] + y * spacing[1], origin[2] + z * spacing[2]]

    # Echo voxels (above the floor) with their weights; the bright ones seed the lines.
    echo = []
    for z in range(nz):
        for y in range(ny):
            row = nx * (y + ny * z)
            for x in range(nx):
                v = vox[x + row]
                if v > floor:
                    echo.append((phys(x, y, z), v - floor, v >= thr))
    bright = [e for e in echo if e[2]]
    rng = random.Random(args.seed)
    wires = []
    remaining = list(range(len(bright)))
    while len(wires) < args.max_wires and len(remaining) >= args.min_voxels:
        pts = [bright[i][0] for i in remaining]
        wts = [bright[i][1] for i in remaining]
        best = None
        for _ in range(args.iterations):
            a, b = rng.sample(range(len(pts)), 2)
            d = [pts[b][k] - pts[a][k] for k in range(3)]
            norm = math.sqrt(sum(x * x for x in d))
            if norm < args.min_length_mm / 2:
                continue
            d = [x / norm for x in d]
            score = 0.0
            for p, w in zip(pts, wts):
                if perp_dist(p, pts[a], d)[0] <= args.inlier_mm:
                    score += w
            if best is None or score > best[0]:
                best = (score, pts[a], d)
        if best is None:
            break
        _, c, d = best
        # Refine: intensity-weighted least squares on every echo voxel near the line, three
        # passes; the segment is the extent of the bright inliers.
        for _ in range(3):
            near = [(p, w) for p, w, _b in echo if perp_dist(p, c, d)[0] <= args.radius_mm]
            if len(near) < args.min_voxels:
                break
            c, d, _vals = weighted_line([p for p, _ in near], [w for _, w in near])
        inl = [i for i in remaining if perp_dist(bright[i][0], c, d)[0] <= args.inlier_mm]
        if len(inl) < args.min_voxels:
            break
        ts = sorted(perp_dist(bright[i][0], c, d)[1] for i in inl)
        # The longest run of inliers without a gap over --max-gap-mm: one wire's echo.
        runs, start = [], 0
        for k in range(1, len(ts) + 1):
            if k == len(ts) or ts[k] - ts[k - 1] > args.max_gap_mm:
                runs.append((ts[k - 1] - ts[start], start, k))
                start = k
        length, r0, r1 = max(runs)
        lo_t, hi_t = ts[r0], ts[r1 - 1]
        inl_set = set(inl)
        remaining = [i for i in remaining if i not in inl_set]
        if length < args.min_length_mm:
            continue
        # Final fit on the echo voxels of that run.
        near = [(p, w) for p, w, _b in echo
                if perp_dist(p, c, d)[0] <= args.radius_mm and lo_t - 1 <= perp_dist(p, c, d)[1] <= hi_t + 1]
        c, d, _vals = weighted_line([p for p, _ in near], [w for _, w in near])
        wsum = sum(w for _, w in near)
        rms = math.sqrt(sum(w * perp_dist(p, c, d)[0] ** 2 for p, w in near) / wsum)
        ts = [perp_dist(p, c, d)[1] for p, _ in near]
        wires.append({
            "center_mm": [round(x, 3) for x in c],
            "direction": [round(x, 5) for x in d],
            "length_mm": round(max(ts) - min(ts), 2),
            "rms_mm": round(rms, 3),
            "voxels": len(near),
            "bright_inliers": len(inl),
        })
    wires.sort(key=lambda w: -w["length_mm"])
    return thr, floor, wires


def line_metrics(wire, point, direction):
    c, d = wire["center_mm"], wire["direction"]
    n = math.sqrt(sum(x * x for x in direction))
    e = [x / n for x in direction]
    cosang = abs(sum(d[k] * e[k] for k in range(3)))
    angle = math.degrees(math.acos(min(1.0, cosang)))
    centre_dist, _ = perp_dist(c, point, e)
    cross = [d[1] * e[2] - d[2] * e[1], d[2] * e[0] - d[0] * e[2], d[0] * e[1] - d[1] * e[0]]
    cn = math.sqrt(sum(x * x for x in cross))
    if cn < 1e-9:
        line_dist = centre_dist
    else:
        line_dist = abs(sum((point[k] - c[k]) * cross[k] for k in range(3))) / cn
    return round(angle, 2), round(centre_dist, 3), round(line_dist, 3)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("volume")
    ap.add_argument("--threshold", type=float, default=40.0)
    ap.add_argument("--floor", type=float)
    ap.add_argument("--min-voxels", type=int, default=15)
    ap.add_argument("--min-length-mm", type=float, default=8.0)
    ap.add_argument("--radius-mm", type=float, default=1.5)
    ap.add_argument("--inlier-mm", type=float, default=1.0)
    ap.add_argument("--max-gap-mm", type=float, default=4.0)
    ap.add_argument("--max-wires", type=int, default=12)
    ap.add_argument("--iterations", type=int, default=300)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--detect", help="JSON of `echoservo detect VOLUME --json`")
    args = ap.parse_args()
    dims, spacing, origin, vox = read_mha(args.volume)
    thr, floor, wires = find_wires(dims, spacing, origin, vox, args)
    out = {"volume": args.volume, "dims": dims, "spacing_mm": spacing, "origin_mm": origin,
           "threshold": thr, "floor": floor, "wires": wires}
    if args.detect:
        with open(args.detect) as f:
            det = json.load(f)
        frames = det.get("frames", [det])
        frame = frames[0]
        if not frame.get("axis_point") or not frame.get("axis_direction"):
            out["detection"] = {"found": False}
        else:
            p, e = frame["axis_point"], frame["axis_direction"]
            per_wire = []
            for i, w in enumerate(wires):
                angle, cd, ld = line_metrics(w, p, e)
                per_wire.append({"wire": i, "angle_deg": angle, "centre_to_axis_mm": cd,
                                 "line_distance_mm": ld})
            out["detection"] = {"found": True, "axis_point": p, "axis_direction": e,
                                "per_wire": per_wire}
    json.dump(out, sys.stdout, indent=2)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
