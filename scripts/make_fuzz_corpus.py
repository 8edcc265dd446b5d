#!/usr/bin/env python3
"""Writes the derived seed inputs of the fuzz corpora (tests/fuzz/corpus/, README there).

Real files from data/ are copied unchanged when small; big PLUS/MetaImage/NRRD files are
shrunk to a few frames cropped to a few pixels (header fields kept, data re-compressed the
way the original was), so that every seed runs in well under a millisecond. The DDS seeds
are CDR (little-endian) encodings of plausible samples. Run from the repository root:
    python3 scripts/make_fuzz_corpus.py
"""
import gzip
import os
import re
import shutil
import struct
import zlib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "data")
OUT = os.path.join(ROOT, "tests", "fuzz", "corpus")


def out(target, name, data, prefix=b""):
    d = os.path.join(OUT, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(prefix + data)


def shrink_mha(src, frames, crop, volume=False):
    raw = open(src, "rb").read()
    end = raw.index(b"ElementDataFile")
    end = raw.index(b"\n", end) + 1
    header, data = raw[:end].decode("latin-1"), raw[end:]
    dims = [int(v) for v in re.search(r"^DimSize\s*=\s*(.*)$", header, re.M).group(1).split()]
    compressed = re.search(r"^CompressedData\s*=\s*True", header, re.M) is not None
    if compressed:
        size = int(re.search(r"^CompressedDataSize\s*=\s*(\d+)", header, re.M).group(1))
        data = zlib.decompress(data[:size])
    if volume:  # one 3D volume: crop every axis
        frame_dims, n = dims, 1
    else:
        *frame_dims, n = dims
    k = min(frames, n)
    frame_bytes = 1
    for v in frame_dims:
        frame_bytes *= v
    new_dims = [min(v, crop) for v in frame_dims]
    pixels = bytearray()
    for f in range(k):
        frame = data[f * frame_bytes:(f + 1) * frame_bytes]
        if len(frame_dims) == 2 and frame_bytes:
            x, y = frame_dims
            for j in range(new_dims[1]):
                pixels += frame[j * x:j * x + new_dims[0]]
        elif len(frame_dims) == 3 and frame_bytes:
            x, y, z = frame_dims
            for kk in range(new_dims[2]):
                for j in range(new_dims[1]):
                    o = kk * x * y + j * x
                    pixels += frame[o:o + new_dims[0]]
    if volume:
        new_dims_all = new_dims
    else:
        new_dims_all = new_dims + [k]
    lines = []
    for line in header.splitlines(keepends=True):
        m = re.match(r"Seq_Frame(\d+)_", line)
        if m and int(m.group(1)) >= k:
            continue
        if line.startswith("DimSize"):
            line = "DimSize = " + " ".join(str(v) for v in new_dims_all) + "\n"
        lines.append(line)
    body = bytes(pixels)
    if compressed:
        body = zlib.compress(body)
        lines = [("CompressedDataSize = %d\n" % len(body)) if l.startswith("CompressedDataSize") else l
                 for l in lines]
    return "".join(lines).encode("latin-1") + body


def shrink_nrrd(src, frames, crop):
    raw = open(src, "rb").read()
    end = raw.index(b"\n\n") + 2
    header, data = raw[:end].decode("latin-1"), raw[end:]
    sizes = [int(v) for v in re.search(r"^sizes:\s*(.*)$", header, re.M).group(1).split()]
    data = gzip.decompress(data)
    x, y, n = sizes
    k = min(frames, n)
    cx, cy = min(x, crop), min(y, crop)
    pixels = bytearray()
    for f in range(k):
        for j in range(cy):
            o = f * x * y + j * x
            pixels += data[o:o + cx]
    lines = []
    for line in header.splitlines(keepends=True):
        m = re.match(r"Seq_Frame(\d+)_", line)
        if m and int(m.group(1)) >= k:
            continue
        if line.startswith("sizes:"):
            line = "sizes: %d %d %d\n" % (cx, cy, k)
        lines.append(line)
    return "".join(lines).encode("latin-1") + gzip.compress(bytes(pixels), mtime=0)


def cdr(fmt_fields):
    """CDR little-endian body with the encapsulation header; fields are (type, value)."""
    body = bytearray()

    def align(n):
        while len(body) % n:
            body.append(0)

    for kind, value in fmt_fields:
        if kind == "u64":
            align(8); body += struct.pack("<Q", value)
        elif kind == "u8":
            body += struct.pack("<B", value)
        elif kind == "u32":
            align(4); body += struct.pack("<I", value)
        elif kind == "f64":
            align(8); body += struct.pack("<d", value)
        elif kind == "seq":
            align(4); body += struct.pack("<I", len(value))
            for v in value:
                align(8); body += struct.pack("<d", v)
    return b"\x00\x01\x00\x00" + bytes(body)


def main():
    plus = os.path.join(DATA, "plus")
    igtl = os.path.join(DATA, "openigtlink")
    # OpenIGTLink: every reference message, and two IMAGE messages back to back (a stream).
    for name in sorted(os.listdir(igtl)):
        if name.endswith(".bin"):
            shutil.copy(os.path.join(igtl, name), os.path.join(OUT, "igtl_message", name))
    image = open(os.path.join(igtl, "test_image_message.bin"), "rb").read()
    status = open(os.path.join(igtl, "test_status_message.bin"), "rb").read()
    out("igtl_message", "stream_image_status_image.bin", image + status + image)
    shutil.copy(os.path.join(igtl, "LICENSE.txt"), os.path.join(OUT, "igtl_message", "LICENSE.txt"))

    # PLUS sequences.
    shutil.copy(os.path.join(plus, "Prostate10_tracker.igs.mha"), os.path.join(OUT, "plus_sequence"))
    seqs = {
        "NwirePhantomFreehand_2f_8px.igs.mha": shrink_mha(os.path.join(plus, "NwirePhantomFreehand.igs.mha"), 2, 8),
        "NwirePhantomFreehand_2f_8px.igs.nrrd": shrink_nrrd(os.path.join(plus, "NwirePhantomFreehand.igs.nrrd"), 2, 8),
        "WaterTank_4f.igs.mha": shrink_mha(os.path.join(plus, "WaterTankBottomTranslationTrackerBuffer-trimmed.igs.mha"), 4, 8),
        "TransformInterpolation_9f.igs.mha": shrink_mha(os.path.join(plus, "TransformInterpolationTest.igs.mha"), 9, 8),
        "TimestampFiltering_4f.igs.mha": shrink_mha(os.path.join(plus, "TimestampFilteringTest.igs.mha"), 4, 8),
    }
    for name, data in seqs.items():
        out("plus_sequence", name, data)
    shutil.copy(os.path.join(plus, "LICENSE"), os.path.join(OUT, "plus_sequence", "LICENSE"))

    # Single volumes: byte 0 even = .mha, odd = .nrrd.
    vol = shrink_mha(os.path.join(plus, "SpinePhantomFreehandReconstructed.mha"), 1, 8, volume=True)
    out("volume_io", "SpinePhantomReconstructed_8px.mha", vol, b"\x00")
    hdr_end = vol.index(b"ElementDataFile"); hdr_end = vol.index(b"\n", hdr_end) + 1
    body = zlib.decompress(vol[hdr_end:])
    raw = vol[:hdr_end].replace(b"CompressedData = True", b"CompressedData = False")
    raw = re.sub(rb"CompressedDataSize = \d+\n", b"", raw) + body
    out("volume_io", "SpinePhantomReconstructed_8px_raw.mha", raw, b"\x00")
    out("volume_io", "NwirePhantom_2f_8px.nrrd", seqs["NwirePhantomFreehand_2f_8px.igs.nrrd"], b"\x01")
    shutil.copy(os.path.join(plus, "LICENSE"), os.path.join(OUT, "volume_io", "LICENSE"))

    # EM logs: byte 0 = format (0 auto .csv, 1 Aurora, 2 sim, 3 PLUS .igs.mha), byte 1 = sensor.
    aurora = open(os.path.join(DATA, "em_tracker", "NDIdata_snakeravenTest_2_2_21.csv"), "rb").read()
    head = b"".join(aurora.splitlines(keepends=True)[:40])
    out("em_log", "aurora_40rows_sensor1.csv", head, b"\x00\x01")
    out("em_log", "aurora_40rows_sensorb.csv", head, b"\x01\x02")
    sim = b"t_s,x_mm,y_mm,z_mm,valid\n0.000,1.5,2.5,30.25,1\n0.025,1.6,2.4,30.5,1\n0.050,0,0,0,0\n0.075,1.8,2.2,31,1\n"
    out("em_log", "sim_em.csv", sim, b"\x02\x00")
    out("em_log", "WaterTank_4f_stylus.igs.mha", seqs["WaterTank_4f.igs.mha"], b"\x03\x03")
    out("em_log", "Prostate10_tracker.igs.mha", open(os.path.join(plus, "Prostate10_tracker.igs.mha"), "rb").read(), b"\x03\x00")
    shutil.copy(os.path.join(DATA, "em_tracker", "LICENSE"), os.path.join(OUT, "em_log", "LICENSE-em_tracker"))
    shutil.copy(os.path.join(plus, "LICENSE"), os.path.join(OUT, "em_log", "LICENSE-plus"))

    # Trials: JSON, a NUL byte, the CSV (no NUL: the CSV alone with a default JSON).
    example_json = (b'{\n  "sheath_id_mm": 1.6,\n  "guidewire_od_mm": 0.8,\n  "bends": [\n'
                    b'    {"angle_deg": 90.0, "radius_mm": 50.0},\n    {"angle_deg": 90.0, "radius_mm": 25.0}\n'
                    b'  ],\n  "tip_load_n": 0.0,\n  "meta": {"operator": "x", "run": 17}\n}\n')
    example_csv = (b"t,base_cmd,base,tip,force,motor_current_a\n0,0,0,0,0,0.12\n0.001,0.01,0.0094,0,0.003,0.35\n"
                   b"0.002,0.02,0.0191,0.0012,0.011,0.36\n0.003,0.03,0.0288,0.0071,0.019,0.36\n")
    out("trial_io", "trial_format_example.bin", example_json + b"\0" + example_csv)
    heart = open(os.path.join(DATA, "heart_motion", "phantom_20hz.csv"), "rb").read().splitlines(keepends=True)
    out("trial_io", "heart_motion_30rows.csv", b"".join(heart[:31]))
    renamed = [b"t,base_cmd,base,tip,force,AP1_y,AP1_z,AP2_x,AP2_y,AP2_z,AP3_x,AP3_y,AP3_z\r\n"]
    renamed += [l.rstrip(b"\n") + b"\r\n" for l in heart[1:31]]
    out("trial_io", "heart_motion_as_trial_crlf.bin", example_json + b"\0" + b"\xef\xbb\xbf" + b"".join(renamed))
    shutil.copy(os.path.join(DATA, "heart_motion", "LICENSE"), os.path.join(OUT, "trial_io", "LICENSE-heart_motion"))

    # DDS samples: byte 0 = type (0 target, 1 state, 2 command), byte 1 = receiver clock.
    target = cdr([("u64", 42), ("f64", 99.95), ("f64", 99.97),
                  ("f64", 1.0), ("f64", -2.0), ("f64", 60.0),
                  ("f64", 0.0), ("f64", 0.0), ("f64", 1.0),
                  ("f64", 1.0), ("f64", -2.0), ("f64", 55.0),
                  ("f64", 99.9), ("f64", 0.3), ("f64", 1.25), ("f64", 60.0), ("f64", 0.1),
                  ("seq", [3.0, 0.8, 0.2]), ("seq", [1.0, -0.4, 0.05]),
                  ("f64", 100.5), ("f64", 0.9)])
    out("dds_samples", "target_estimate.cdr", target, b"\x00\x80")
    state = cdr([("u64", 7), ("f64", 99.99), ("u8", 1), ("u32", 0), ("u64", 0),
                 ("f64", 12.5), ("f64", 40.0), ("f64", 55.0), ("f64", 55.5), ("f64", 0.2),
                 ("f64", 4.5), ("f64", 0.06)])
    out("dds_samples", "catheter_state.cdr", state, b"\x01\x80")
    command = cdr([("u64", 3), ("f64", 99.99), ("u8", 1), ("f64", 5.0)])
    out("dds_samples", "servo_command_enable.cdr", command, b"\x02\x80")


if __name__ == "__main__":
    main()
