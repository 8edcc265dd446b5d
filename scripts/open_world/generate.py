#!/usr/bin/env python3
"""Open-world data generator for the echoservo model lab (docs/open_world_generator.md).

An independent bench simulator, written from the physical laws alone (it shares no code
and no implementation choices with echoservo's simulator), that writes catheter datasets
(docs/trial_format.md) and target-motion traces (docs/predictor.md), each with a hidden
effect outside the lab's catalog (or none), plus the ground truth in truth.json.

  python3 scripts/open_world/generate.py --out DIR [--case NAME | --all]
          [--trials N] [--duration S] [--seed K] [--list]

Pure Python 3 standard library; deterministic from --seed (each case has its own
random stream, so one case regenerated alone is identical to the same case in --all).
Units: mm, s, N, kg.
"""
import argparse
import json
import math
import os
import random
import sys
import zlib

# --------------------------------------------------------------------------------------
# Bench constants (the seed physics)
# --------------------------------------------------------------------------------------
RATE_HZ = 1000.0          # sample rate of the trial CSV
SUBSTEPS = 5              # internal steps per sample (0.2 ms) for the friction and tip states
F_COULOMB_N = 0.95        # Coulomb friction along the sheath
MU_TIP = 0.32             # Coulomb coefficient for the tip load
B_VISCOUS = 0.0062        # N/(mm/s)
X_PRESLIDE_MM = 0.001     # bristle (presliding) length of the friction model
FORCE_SIGMA_N = 0.0075
FORCE_QUANTUM_N = 0.002
TIP_SIGMA_MM = 0.03
TIP_QUANTUM_MM = 0.0125
BASE_QUANTUM_MM = 0.001
TIP_OFFSET_MM = 0.5       # per-trial tip-sensor offset, uniform in [-0.5, 0.5]
TRAVEL_MM = 10.0          # base stays inside [-10, 10] mm
V_MAX = 150.0             # mm/s
A_MAX = 3000.0            # mm/s^2

# Geometry: 3 bend configurations x 2 (sheath, guidewire) pairs x 3 tip loads.
BEND_SETS = [
    [{"angle_deg": 90.0, "radius_mm": 50.0}, {"angle_deg": 90.0, "radius_mm": 25.0}],
    [{"angle_deg": 60.0, "radius_mm": 40.0}],
    [{"angle_deg": 90.0, "radius_mm": 50.0}, {"angle_deg": 90.0, "radius_mm": 30.0},
     {"angle_deg": 45.0, "radius_mm": 20.0}],
]
TUBES = [(1.6, 0.8), (1.3, 0.9)]  # (sheath_id_mm, guidewire_od_mm): gaps 0.8 and 0.4 mm
TIP_LOADS = [0.0, 0.5, 1.0]

# Motion traces
MOTION_RATE_HZ = 30.0
MOTION_DURATION_S = 60.0
MOTION_SIGMA_MM = 0.25

# --------------------------------------------------------------------------------------
# Cases
# --------------------------------------------------------------------------------------
CASES = {
    "null": {
        "kind": "catheter", "hidden_effect": None, "channel": None, "variable": None,
        "equation": "none: force = bristle Coulomb+viscous friction, tip = play operator of "
                    "width theta*gap around the base (seed physics only)",
        "parameters": {},
    },
    "inertia": {
        "kind": "catheter", "hidden_effect": "inertia", "channel": "force",
        "variable": "acceleration_mm_s2",
        "equation": "force += m * a * 1e-3  [N]; m in kg, a = base acceleration in mm/s^2 "
                    "(moving mass between the force sensor and the guidewire)",
        "parameters": {"mass_kg": 0.065},
    },
    "tight_spot": {
        "kind": "catheter", "hidden_effect": "tight_spot", "channel": "force",
        "variable": "base_mm",
        "equation": "friction magnitude += A * exp(-((base - x0)/w)^2)  [N]; base, x0, w in mm "
                    "(a narrowing of the sheath at one base position)",
        "parameters": {"amplitude_n": 0.4, "x0_mm": 3.0, "width_mm": 1.5},
    },
    "friction_growth": {
        "kind": "catheter", "hidden_effect": "friction_growth", "channel": "force",
        "variable": "time_s",
        "equation": "friction magnitude *= (1 + k * t)  [1]; k in 1/s, t = time since the "
                    "trial start in s (lubricant squeezed out during a trial)",
        "parameters": {"k_per_s": 0.08},
    },
    "sensor_drift": {
        "kind": "catheter", "hidden_effect": "sensor_drift", "channel": "tip",
        "variable": "time_s",
        "equation": "tip reading += d * t  [mm]; d in mm/s, t = time since the trial start "
                    "in s (tip sensor warming up; re-zeroed before each trial)",
        "parameters": {"d_mm_per_s": 0.08},
    },
    "motion_null": {
        "kind": "motion", "hidden_effect": None, "channel": None, "variable": None,
        "equation": "none: x = c + sum_{k=1,2} a_k cos(k phi) + b_k sin(k phi), phi = "
                    "2 pi f t (+ tiny beat-to-beat jitter)",
        "parameters": {},
    },
    "motion_amplitude_growth": {
        "kind": "motion", "hidden_effect": "amplitude_growth", "channel": "position",
        "variable": "cardiac_phase_x_time",
        "equation": "x = c + (1 + g * t / T) * beat(phi)  [mm]; g dimensionless, t and "
                    "T (trace duration) in s (contractility rising during the recording)",
        "parameters": {"g": 0.6},
    },
    "motion_baseline_drift": {
        "kind": "motion", "hidden_effect": "baseline_drift", "channel": "position",
        "variable": "time_s",
        "equation": "x = beat(phi) + c + d1 * (t/T) + d2 * (t/T)^2  [mm]; d1, d2 in mm, "
                    "t and T in s (probe settling on the chest, not periodic)",
        "parameters": {"d1_mm": 3.0, "d2_mm": 1.5},
    },
}


def case_rng(seed, name):
    """An independent, deterministic random stream per (seed, case)."""
    return random.Random(seed * 1000003 + zlib.crc32(name.encode()))


# --------------------------------------------------------------------------------------
# Bench trajectory: analytic pieces with continuous position and velocity
# --------------------------------------------------------------------------------------
class Piece:
    __slots__ = ("t0", "dur", "kind", "x0", "p")

    def __init__(self, t0, dur, kind, x0, p):
        self.t0, self.dur, self.kind, self.x0, self.p = t0, dur, kind, x0, p

    def at(self, tau):
        """(position mm, velocity mm/s, acceleration mm/s^2) at tau s into the piece."""
        k, x0, p = self.kind, self.x0, self.p
        if k == "rest":
            return x0, 0.0, 0.0
        if k == "cruise":
            return x0 + p[0] * tau, p[0], 0.0
        if k == "blend":  # raised-cosine velocity change v1 -> v2 over dur
            v1, dv = p
            T = self.dur
            s = math.pi * tau / T
            x = x0 + v1 * tau + 0.5 * dv * (tau - T / math.pi * math.sin(s))
            return x, v1 + 0.5 * dv * (1.0 - math.cos(s)), 0.5 * dv * math.pi / T * math.sin(s)
        if k == "swing":  # x0 + dir*A*(1 - cos w tau)
            sgn_a, w = p
            c, s = math.cos(w * tau), math.sin(w * tau)
            return x0 + sgn_a * (1.0 - c), sgn_a * w * s, sgn_a * w * w * c
        raise ValueError(k)

    def end(self):
        return self.at(self.dur)[0]


class Trajectory:
    def __init__(self):
        self.pieces = []
        self.t = 0.0
        self.x = 0.0

    def add(self, kind, dur, p=()):
        if dur <= 0:
            return
        piece = Piece(self.t, dur, kind, self.x, p)
        self.pieces.append(piece)
        self.t += dur
        self.x = piece.end()

    def rest(self, dur):
        self.add("rest", dur)

    def sweep(self, target, speeds, accel):
        """Moves to `target` through speed plateaus `speeds` (mm/s, > 0), blends at
        peak acceleration `accel`; starts and ends at rest."""
        dist = target - self.x
        sgn = 1.0 if dist >= 0 else -1.0
        dist = abs(dist)
        if dist < 1e-9:
            return
        for _ in range(60):
            vs = [0.0] + list(speeds) + [0.0]
            blends = []
            used = 0.0
            for a, b in zip(vs[:-1], vs[1:]):
                T = math.pi * abs(b - a) / (2.0 * accel)
                blends.append(T)
                used += 0.5 * (a + b) * T
            if used <= dist:
                break
            speeds = [0.8 * s for s in speeds]
        cruise = (dist - used) / len(speeds)
        for i, v in enumerate(speeds):
            self.add("blend", blends[i], (sgn * vs[i], sgn * (v - vs[i])))
            self.add("cruise", cruise / v, (sgn * v,))
        self.add("blend", blends[-1], (sgn * speeds[-1], -sgn * speeds[-1]))
        self.x = self.pieces[-1].end() if self.pieces else self.x

    def swing(self, amp, freq, half_cycles, sgn):
        w = 2.0 * math.pi * freq
        self.add("swing", half_cycles * math.pi / w, (sgn * amp, w))


def room(x, sgn):
    return (TRAVEL_MM - x) if sgn > 0 else (x + TRAVEL_MM)


def make_trajectory(rng, duration):
    tr = Trajectory()
    tr.x = rng.uniform(-3.0, 3.0)
    tr.rest(rng.uniform(0.03, 0.12))
    while tr.t < duration:
        kind = rng.choices(["swing", "triangle", "steps", "slow"], [4, 3, 2, 1])[0]
        sgn = 1.0 if room(tr.x, 1.0) >= room(tr.x, -1.0) else -1.0
        if rng.random() < 0.3 and room(tr.x, -sgn) > 4.0:
            sgn = -sgn
        space = room(tr.x, sgn)
        if kind == "swing":
            amp = rng.uniform(1.5, max(1.6, min(8.0, space / 2.0)))
            fmax = min(3.0, V_MAX / (2 * math.pi * amp), math.sqrt(A_MAX / amp) / (2 * math.pi))
            freq = rng.uniform(min(0.4, fmax), fmax) if rng.random() < 0.5 else rng.uniform(0.6 * fmax, fmax)
            n = rng.randint(1, 6)
            while n > 1 and n / (2 * freq) > 1.6:
                n -= 1
            tr.swing(amp, freq, n, sgn)
        elif kind == "triangle":
            if rng.random() < 0.5:  # fast: most of the travel, 90-150 mm/s
                sgn = 1.0 if room(tr.x, 1.0) >= room(tr.x, -1.0) else -1.0
                space = room(tr.x, sgn)
                d = rng.uniform(0.8 * space, space)
                v = rng.uniform(90.0, V_MAX)
                acc = rng.uniform(2000.0, A_MAX)
            else:
                d = rng.uniform(min(4.0, space), space)
                v = rng.uniform(10.0, 90.0)
                acc = rng.uniform(300.0, A_MAX)
            start = tr.x
            tr.sweep(tr.x + sgn * d, [v], acc)
            if rng.random() < 0.6:
                tr.rest(rng.uniform(0.05, 0.3))
            tr.sweep(start, [v], acc)
        elif kind == "steps":
            d = rng.uniform(min(6.0, space), space)
            speeds = [rng.uniform(5.0, V_MAX) for _ in range(rng.randint(2, 3))]
            tr.sweep(tr.x + sgn * d, speeds, rng.uniform(1000.0, A_MAX))
        else:  # slow creep: the 0-10 mm/s range
            d = rng.uniform(0.5, min(3.0, max(0.6, space)))
            tr.sweep(tr.x + sgn * d, [rng.uniform(1.5, 10.0)], rng.uniform(200.0, 1500.0))
        if rng.random() < 0.6:
            tr.rest(rng.uniform(0.03, 0.35))
    tr.rest(1.0)  # covers the end of the trial
    return tr


def sample_trajectory(tr, times):
    """(x, v, a) lists at the given increasing times."""
    xs, vs, accs = [], [], []
    i = 0
    pieces = tr.pieces
    for t in times:
        while i + 1 < len(pieces) and t >= pieces[i + 1].t0:
            i += 1
        x, v, a = pieces[i].at(t - pieces[i].t0)
        xs.append(x)
        vs.append(v)
        accs.append(a)
    return xs, vs, accs


# --------------------------------------------------------------------------------------
# Catheter physics
# --------------------------------------------------------------------------------------
def quantise(x, q):
    return round(x / q) * q


def geometry(i):
    bends = BEND_SETS[i % 3]
    sheath, wire = TUBES[i % 2]
    load = TIP_LOADS[(i // 2) % 3]
    return {"sheath_id_mm": sheath, "guidewire_od_mm": wire, "bends": bends, "tip_load_n": load}


def simulate_trial(rng, case, geom, duration):
    """One trial: returns the CSV rows (t, base_cmd, base, tip, force) and the meta."""
    params = CASES[case]["parameters"]
    theta = sum(b["angle_deg"] for b in geom["bends"]) * math.pi / 180.0
    gap = geom["sheath_id_mm"] - geom["guidewire_od_mm"]
    width = theta * gap
    f_dry = F_COULOMB_N + MU_TIP * geom["tip_load_n"]

    tr = make_trajectory(rng, duration)
    n = int(round(duration * RATE_HZ))
    dt = 1.0 / RATE_HZ
    h = dt / SUBSTEPS
    fine_t = [k * h for k in range(n * SUBSTEPS + 1)]
    fx, fv, fa = sample_trajectory(tr, fine_t)
    mid_t = [(k + 0.5) * h for k in range(n * SUBSTEPS)]
    mx, mv, _ = sample_trajectory(tr, mid_t)

    def friction_magnitude(speed, x, t):
        f = f_dry + B_VISCOUS * speed
        if case == "friction_growth":
            f *= 1.0 + params["k_per_s"] * t
        if case == "tight_spot":
            f += params["amplitude_n"] * math.exp(-((x - params["x0_mm"]) / params["width_mm"]) ** 2)
        return f

    # Initial states: friction bristles pre-loaded anywhere within the breakaway band,
    # the tip anywhere inside the play band.
    force_state = rng.uniform(-1.0, 1.0) * friction_magnitude(0.0, fx[0], 0.0)
    seed_state = force_state  # the same bristles without the hidden effect (for its size)
    tip_state = fx[0] + rng.uniform(-1.0, 1.0) * width / 2.0
    offset = rng.uniform(-TIP_OFFSET_MM, TIP_OFFSET_MM)
    rows = []
    effect_sq = 0.0
    for i in range(n):
        k = i * SUBSTEPS
        t = i * dt
        if i > 0:
            for j in range(k - SUBSTEPS, k):
                dx = fx[j + 1] - fx[j]
                if dx != 0.0:
                    target = math.copysign(friction_magnitude(abs(mv[j]), mx[j], mid_t[j]), dx)
                    decay = math.exp(-abs(dx) / X_PRESLIDE_MM)
                    force_state = target + (force_state - target) * decay
                    target0 = math.copysign(f_dry + B_VISCOUS * abs(mv[j]), dx)
                    seed_state = target0 + (seed_state - target0) * decay
                drive = fx[j + 1]
                lo, hi = drive - width / 2.0, drive + width / 2.0
                if tip_state < lo:
                    tip_state = lo
                elif tip_state > hi:
                    tip_state = hi
        force = force_state
        if case == "inertia":
            force += params["mass_kg"] * fa[k] * 1e-3
        tip = tip_state + offset
        if case == "sensor_drift":
            tip += params["d_mm_per_s"] * t
            effect_sq += (params["d_mm_per_s"] * t) ** 2
        else:
            effect_sq += (force - seed_state) ** 2
        force_meas = quantise(force + rng.gauss(0.0, FORCE_SIGMA_N), FORCE_QUANTUM_N)
        tip_meas = quantise(tip + rng.gauss(0.0, TIP_SIGMA_MM), TIP_QUANTUM_MM)
        base_meas = quantise(fx[k], BASE_QUANTUM_MM)
        rows.append((t, fx[k], base_meas, tip_meas, force_meas))
    peak_v = max(abs(v) for v in fv)
    peak_a = max(abs(a) for a in fa)
    meta = {"generator": "scripts/open_world/generate.py", "case": case,
            "tip_offset_mm": round(offset, 6), "backlash_width_mm": round(width, 6),
            "peak_speed_mm_s": round(peak_v, 3), "peak_accel_mm_s2": round(peak_a, 1),
            "base_range_mm": [round(min(fx), 4), round(max(fx), 4)]}
    return rows, meta, effect_sq


def fmt(x, decimals):
    s = "%.*f" % (decimals, x)
    if s.startswith("-") and float(s) == 0.0:
        s = s[1:]
    return s


def write_catheter_case(out_dir, case, trials, duration, seed):
    rng = case_rng(seed, case)
    os.makedirs(out_dir, exist_ok=True)
    stats = []
    effect_sq = 0.0
    samples = 0
    for i in range(trials):
        geom = geometry(i)
        rows, meta, sq = simulate_trial(rng, case, geom, duration)
        effect_sq += sq
        samples += len(rows)
        meta["seed"] = seed
        meta["trial"] = i
        stem = os.path.join(out_dir, "trial_%03d" % i)
        doc = dict(geom)
        doc["meta"] = meta
        with open(stem + ".json", "w") as f:
            json.dump(doc, f, indent=2)
            f.write("\n")
        with open(stem + ".csv", "w") as f:
            f.write("t,base_cmd,base,tip,force\n")
            f.write("".join("%s,%s,%s,%s,%s\n" % (fmt(t, 3), repr(round(c, 9)) if c != 0 else "0",
                                                   fmt(b, 3), fmt(tp, 4), fmt(fo, 3))
                            for t, c, b, tp, fo in rows))
        stats.append(meta)
    return {"trials": trials, "duration_s": duration, "rate_hz": RATE_HZ,
            "noise": {"tip_mm": TIP_SIGMA_MM, "force_n": FORCE_SIGMA_N},
            "quantum": {"tip_mm": TIP_QUANTUM_MM, "force_n": FORCE_QUANTUM_N,
                        "base_mm": BASE_QUANTUM_MM},
            "seed_physics": {"coulomb_n": F_COULOMB_N, "mu_tip": MU_TIP,
                             "viscous_n_per_mm_s": B_VISCOUS,
                             "presliding_mm": X_PRESLIDE_MM,
                             "backlash": "B = theta * gap"},
            "peak_speed_mm_s": max(s["peak_speed_mm_s"] for s in stats),
            "peak_accel_mm_s2": max(s["peak_accel_mm_s2"] for s in stats),
            "effect_rms": effect_rms(case, math.sqrt(effect_sq / samples))}


def effect_rms(case, rms):
    """The hidden effect's RMS contribution to its channel (before anything a model could
    absorb, e.g. a per-trial offset) and its mean square in noise variances."""
    channel = CASES[case]["channel"]
    if channel is None:
        return None
    sigma = {"force": FORCE_SIGMA_N, "tip": TIP_SIGMA_MM, "position": MOTION_SIGMA_MM}[channel]
    unit = {"force": "n", "tip": "mm", "position": "mm"}[channel]
    return {"channel": channel, "rms_" + unit: round(rms, 6),
            "noise_variances": round((rms / sigma) ** 2, 2)}


# --------------------------------------------------------------------------------------
# Motion traces
# --------------------------------------------------------------------------------------
def write_motion_case(out_dir, case, seed, duration=MOTION_DURATION_S):
    rng = case_rng(seed, case)
    params = CASES[case]["parameters"]
    os.makedirs(out_dir, exist_ok=True)
    bpm = rng.uniform(68.0, 76.0)
    f_hr = bpm / 60.0
    a1 = rng.uniform(4.0, 5.5)                 # mm: 8-11 mm fundamental peak to peak
    b1 = rng.uniform(-0.5, 0.5)
    a2 = rng.uniform(0.8, 1.5) * rng.choice([-1, 1])
    b2 = rng.uniform(0.6, 1.2) * rng.choice([-1, 1])
    c0 = rng.uniform(-2.0, 2.0)
    phi0 = rng.uniform(0.0, 2 * math.pi)
    # Natural variability, kept inside what heartbeat:2 (a constant rate) can follow to
    # well below the noise: beat-to-beat amplitude jitter 0.5 % and a slow phase wander
    # of at most 0.01 rad (a rate wander of about 0.004 bpm).
    jitter = [1.0 + rng.gauss(0.0, 0.005) for _ in range(int(duration * f_hr) + 3)]
    wander_f = rng.uniform(0.03, 0.06)
    rows = []
    effect_sq = 0.0
    n = int(round(duration * MOTION_RATE_HZ)) + 1
    t_prev = -1.0
    for i in range(n):
        t = i / MOTION_RATE_HZ + rng.uniform(-0.002, 0.002)  # volume time stamps jitter ±2 ms
        t = max(t, t_prev + 1e-3, 0.0)
        t_prev = t
        phase = phi0 + 2 * math.pi * f_hr * t + 0.01 * math.sin(2 * math.pi * wander_f * t)
        beat_no = int(math.floor((phase - phi0) / (2 * math.pi)))
        beat = jitter[max(0, beat_no)] * (a1 * math.cos(phase) + b1 * math.sin(phase)
                                          + a2 * math.cos(2 * phase) + b2 * math.sin(2 * phase))
        u = t / duration
        x = c0 + beat
        if case == "motion_amplitude_growth":
            x = c0 + (1.0 + params["g"] * u) * beat
        elif case == "motion_baseline_drift":
            x += params["d1_mm"] * u + params["d2_mm"] * u * u
        effect_sq += (x - c0 - beat) ** 2
        y = x + rng.gauss(0.0, MOTION_SIGMA_MM)
        rows.append((t, y, x))
    with open(os.path.join(out_dir, "trace.csv"), "w") as f:
        f.write("t,position,truth\n")
        f.write("".join("%.4f,%.4f,%.4f\n" % r for r in rows))
    return {"samples": n, "duration_s": duration, "rate_hz": MOTION_RATE_HZ,
            "noise": {"position_mm": MOTION_SIGMA_MM},
            "heart_rate_bpm": round(bpm, 3),
            "beat_mm": {"a1": round(a1, 4), "b1": round(b1, 4), "a2": round(a2, 4),
                        "b2": round(b2, 4), "offset": round(c0, 4)},
            "variability": {"beat_amplitude_jitter": 0.005, "phase_wander_rad": 0.01,
                            "timestamp_jitter_s": 0.002},
            "effect_rms": effect_rms(case, math.sqrt(effect_sq / n))}


def generate(out, case, trials, duration, seed):
    spec = CASES[case]
    out_dir = os.path.join(out, case)
    if spec["kind"] == "catheter":
        info = write_catheter_case(out_dir, case, trials, duration, seed)
    else:
        info = write_motion_case(out_dir, case, seed)
    truth = {k: spec[k] for k in ("kind", "hidden_effect", "channel", "variable", "equation",
                                  "parameters")}
    truth["noise"] = info.pop("noise")
    truth["seed"] = seed
    truth["data"] = info
    with open(os.path.join(out_dir, "truth.json"), "w") as f:
        json.dump(truth, f, indent=2)
        f.write("\n")
    return truth


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", help="output folder (one subfolder per case)")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--case", action="append", choices=sorted(CASES),
                   help="case to write (repeatable); default: all")
    g.add_argument("--all", action="store_true", help="write every case (the default)")
    ap.add_argument("--trials", type=int, default=8, help="trials per catheter case (8)")
    ap.add_argument("--duration", type=float, default=4.0, help="seconds per trial (4)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    a = ap.parse_args(argv)
    if a.list:
        for name, spec in CASES.items():
            print("%-24s %-8s %s" % (name, spec["kind"], spec["hidden_effect"] or "-"))
        return 0
    if not a.out:
        ap.error("--out is required")
    if a.trials < 2:
        ap.error("--trials must be at least 2 (the lab cross-validates over trials)")
    if not (0.5 <= a.duration <= 600):
        ap.error("--duration must be in [0.5, 600] s")
    cases = a.case or list(CASES)
    for name in cases:
        truth = generate(a.out, name, a.trials, a.duration, a.seed)
        print("%-24s %s" % (name, truth["hidden_effect"] or "none"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
