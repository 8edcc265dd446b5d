#!/usr/bin/env python3
"""Second open-world data generator for the echoservo model lab (docs/open_world_generator2.md).

An independent bench and heart-motion simulator, written from the physical laws alone. It
shares no code and no implementation choice with echoservo's simulator (hw/, C++) nor with
the first generator (scripts/open_world/generate.py): a servo-driven base integrated by
semi-implicit Euler at 0.25 ms, LuGre bristle friction with an implicit bristle update,
its own PRNG (SplitMix64 + Marsaglia polar normals), smooth periodic trajectories
(sines, two-tone sines, heartbeat-like, chirps), stratified random geometry, and hidden
effects whose shapes lie outside the lab's term library.

  python3 scripts/open_world2/generate.py --out DIR [--case NAME ... | --all]
          [--trials N] [--duration S] [--seed K] [--motion-duration S] [--list]

Catheter case NAME -> DIR/NAME/ (trial_000.csv/.json, ..., truth.json).
Motion case NAME   -> DIR/NAME.csv (t,position,truth) and DIR/NAME.truth.json.

Pure Python 3 standard library. Deterministic from --seed: the bench trials (geometry,
trajectory, offsets, initial states) are drawn from a stream keyed by (seed, trial) and are
the same in every catheter case; the noise comes from a stream keyed by (seed, case, trial).
A case written alone is byte-identical to the same case written with --all.
Units: mm, s, N, rad (deg in the trial JSON), bpm.
"""
import argparse
import hashlib
import json
import math
import os
import sys

GENERATOR = "scripts/open_world2/generate.py"

# --------------------------------------------------------------------------------------
# Random numbers: SplitMix64 (Steele, Lea, Flood 2014) + Marsaglia's polar method.
# --------------------------------------------------------------------------------------
MASK64 = (1 << 64) - 1


class Stream:
    def __init__(self, *key):
        digest = hashlib.sha256(":".join(str(k) for k in key).encode()).digest()
        self.state = int.from_bytes(digest[:8], "little")
        self.spare = None

    def u64(self):
        self.state = (self.state + 0x9E3779B97F4A7C15) & MASK64
        z = self.state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK64
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK64
        return z ^ (z >> 31)

    def unit(self):
        """Uniform in [0, 1) with 53 random bits."""
        return (self.u64() >> 11) * (1.0 / 9007199254740992.0)

    def between(self, a, b):
        return a + (b - a) * self.unit()

    def index(self, n):
        return int(self.unit() * n)

    def sign(self):
        return 1.0 if self.u64() & 1 else -1.0

    def normal(self):
        if self.spare is not None:
            s, self.spare = self.spare, None
            return s
        while True:
            u = 2.0 * self.unit() - 1.0
            v = 2.0 * self.unit() - 1.0
            q = u * u + v * v
            if 0.0 < q < 1.0:
                f = math.sqrt(-2.0 * math.log(q) / q)
                self.spare = v * f
                return u * f

    def permutation(self, n):
        p = list(range(n))
        for i in range(n - 1, 0, -1):  # Fisher-Yates, drawn from this stream
            j = self.index(i + 1)
            p[i], p[j] = p[j], p[i]
        return p


# --------------------------------------------------------------------------------------
# Bench constants: the seed physics as this bench realises it
# --------------------------------------------------------------------------------------
RATE_HZ = 1000.0
SUB = 4                    # integration steps per 1 ms sample (0.25 ms)
F0_N = 1.04                # Coulomb level of the sheath (wall contact)
MU_TIP = 0.27              # Coulomb coefficient of the tip load
VISC = 0.0058              # viscous coefficient sigma2, N/(mm/s)
SIGMA0 = 1600.0            # LuGre bristle stiffness, N/mm (presliding ~0.65 um at 1 N)
SIGMA1 = 0.0015            # LuGre bristle damping, N/(mm/s)
SERVO_HZ = 35.0            # base position loop: natural frequency
SERVO_ZETA = 0.85          # and damping ratio (with velocity feed-forward)
BASE_Q = 0.0005            # base encoder quantum, mm
TIP_SIGMA = 0.028          # tip sensor noise, mm
TIP_Q = 0.01               # tip sensor quantum, mm
FORCE_SIGMA = 0.0068       # force sensor noise, N
FORCE_Q = 0.0025           # force sensor quantum, N
TIP_OFFSET = 0.4           # per-trial tip-sensor offset, uniform in +-0.4 mm
V_PEAK = 140.0             # trajectories are scaled to at most this base speed, mm/s

TUBES = [(1.25, 0.95), (1.40, 0.90), (1.60, 1.00), (1.55, 0.85), (1.50, 1.05)]  # gaps .3-.7
TIP_LOADS = [0.0, 0.3, 0.6, 0.9, 1.2]
FAMILIES = ["sine", "mitral", "chirp", "two_tone"]

# Motion traces
MOTION_HZ = 25.0
MOTION_SIGMA = 0.2         # mm, white
MOTION_Q = 0.05            # mm, tracker output quantum
MOTION_HARMONICS = 3       # the heartbeat has 3 harmonics: the lab model is heartbeat:3

# --------------------------------------------------------------------------------------
# Cases
# --------------------------------------------------------------------------------------
EFFECTS = {
    "ripple_friction": {
        "channel": "force", "variable": "base_mm", "variables": ["base_mm"],
        "equation": "friction level g += a * (1 + sin(2*pi*base/P + phi)) / 2  [N]; base and "
                    "P in mm, phi in rad (sheath braid: periodic along the guidewire position)",
        "parameters": {"a_n": 0.15, "period_mm": 3.0, "phase_rad": 0.7},
    },
    "friction_step": {
        "channel": "force", "variable": "time_s", "variables": ["time_s"],
        "equation": "friction level g += delta * H(t - t0)  [N]; t = time since the trial "
                    "start in s, H the unit step (lubricant lost / clot at t0)",
        "parameters": {"delta_n": 0.3, "t0_s": 2.0},
    },
    "friction_warmup": {
        "channel": "force", "variable": "time_s", "variables": ["time_s"],
        "equation": "friction (level g and viscous sigma2) *= 1 + a * (1 - exp(-t/tau))  [1]; "
                    "t = time since the trial start in s (coating dries, saturating)",
        "parameters": {"a": 0.3, "tau_s": 1.5},
    },
    "bend_viscous": {
        "channel": "force", "variable": "velocity_mm_s",
        "variables": ["velocity_mm_s", "bend_deg"],
        "equation": "friction += c * theta * |v|  [N]; theta = total bend angle in rad, v = "
                    "base velocity in mm/s (viscous drag grows with the wrapped length)",
        "parameters": {"c_n_per_mm_s_rad": 0.0006},
    },
    "speed_backlash": {
        "channel": "tip", "variable": "velocity_mm_s",
        "variables": ["velocity_mm_s", "bend_deg", "gap_mm"],
        "equation": "deadzone width B = theta * gap * (1 + |v| / v0)  [mm]; theta in rad, gap "
                    "in mm, v = base velocity in mm/s (the wire lifts off the bend wall when fast)",
        "parameters": {"v0_mm_s": 60.0},
    },
    "tip_speed_error": {
        "channel": "tip", "variable": "velocity_mm_s", "variables": ["velocity_mm_s"],
        "equation": "tip reading += k * w * |w|  [mm]; w = tip velocity in mm/s (the base "
                    "velocity once the deadzone is taken up), k in mm/(mm/s)^2 (a "
                    "tracker's dynamic error, not a delay)",
        "parameters": {"k_mm_per_mm_s_sq": 2.5e-5},
    },
}

CATHETER_CASES = {
    "null": [],
    "ripple_friction": ["ripple_friction"],
    "friction_step": ["friction_step"],
    "friction_warmup": ["friction_warmup"],
    "bend_viscous": ["bend_viscous"],
    "speed_backlash": ["speed_backlash"],
    "tip_speed_error": ["tip_speed_error"],
    "ripple_and_tip_speed": ["ripple_friction", "tip_speed_error"],
}

MOTION_EFFECTS = {
    "motion_null": None,
    "motion_jump": {
        "variable": "time_s", "variables": ["time_s"],
        "equation": "x += J * H(t - tj)  [mm]; t in s (the probe or the patient shifts once)",
        "parameters": {"jump_mm": 1.5},
    },
    "motion_rate_swing": {
        "variable": "cardiac_phase_x_time",
        "variables": ["cardiac_phase_x_time", "heart_rate_bpm", "cardiac_phase"],
        "equation": "heart rate f(t) = f0 + df * sin(2*pi*t/Tr + psi), phase = 2*pi * "
                    "integral f dt  [bpm, s] (respiratory sinus arrhythmia)",
        "parameters": {"swing_bpm": 6.0, "period_s": 12.0},
    },
    "motion_amplitude_mod": {
        "variable": "cardiac_phase_x_time", "variables": ["cardiac_phase_x_time"],
        "equation": "x = c + (1 + m * sin(2*pi*t/Tm + psi)) * beat(phase)  [mm]; m "
                    "dimensionless, Tm in s (stroke volume swinging with breathing)",
        "parameters": {"m": 0.25, "period_s": 9.0},
    },
    "motion_beat_jitter": {
        "variable": "cardiac_phase_x_time",
        "variables": ["cardiac_phase_x_time", "cardiac_phase", "heart_rate_bpm"],
        "equation": "each beat j lasts L_j = L0 * (1 + u_j), u_j uniform in [-e, e]; the phase "
                    "runs linearly 0..2*pi over each beat  [s]",
        "parameters": {"e": 0.05},
    },
}

ALL_CASES = list(CATHETER_CASES) + list(MOTION_EFFECTS)


# --------------------------------------------------------------------------------------
# Base trajectories (the servo reference): smooth, periodic families
# --------------------------------------------------------------------------------------
def smoothstep(t, ramp):
    """Quintic start-up envelope and its derivative."""
    if t >= ramp:
        return 1.0, 0.0
    s = t / ramp
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s), 30.0 * s * s * (1.0 - s) ** 2 / ramp


class Reference:
    """r(t) = centre + env(t) * scale * shape(t); shape is a sum of tones with a phase law."""

    def __init__(self, family, rng, duration):
        self.family = family
        self.centre = rng.between(-2.0, 2.0)
        self.ramp = 0.25
        self.duration = duration
        if family == "sine":
            amp = rng.between(2.5, 8.0)
            f = rng.between(0.4, min(2.2, V_PEAK / (2 * math.pi * amp)))
            self.tones = [(amp, f, rng.between(0, 2 * math.pi))]
            self.chirp = None
        elif family == "two_tone":
            f1 = rng.between(0.5, 1.1)
            self.tones = [(rng.between(3.0, 6.0), f1, rng.between(0, 2 * math.pi)),
                          (rng.between(0.8, 2.0), f1 * rng.between(2.3, 4.1),
                           rng.between(0, 2 * math.pi))]
            self.chirp = None
        elif family == "mitral":  # a heartbeat-like base motion: 3 harmonics of 60-100 bpm
            f = rng.between(1.0, 1.67)
            a1 = rng.between(3.0, 5.0)
            self.tones = [(a1, f, rng.between(0, 2 * math.pi)),
                          (a1 * rng.between(0.3, 0.45), 2 * f, rng.between(0, 2 * math.pi)),
                          (a1 * rng.between(0.1, 0.2), 3 * f, rng.between(0, 2 * math.pi))]
            self.chirp = None
        elif family == "chirp":  # linear chirp f0 -> f1 over the trial
            amp = rng.between(3.0, 7.0)
            f_end = min(2.5, V_PEAK / (2 * math.pi * amp)) * rng.between(0.8, 1.0)
            self.tones = [(amp, rng.between(0.25, 0.5), rng.between(0, 2 * math.pi))]
            self.chirp = f_end
        else:
            raise ValueError(family)
        # Scale the excursion to a drawn peak speed, within a travel of 16 mm (and so that
        # the swing stays at least 3 mm, larger than most deadzones).
        self.scale = 1.0
        v_target = rng.between(35.0, V_PEAK)
        grid = [self.at(k * 0.002) for k in range(int(duration / 0.002) + 2)]
        peak = max(abs(d) for _, d in grid)
        span = max(p for p, _ in grid) - min(p for p, _ in grid)
        self.scale = min(v_target / peak, 16.0 / span, V_PEAK / peak)
        self.scale = max(self.scale, min(3.0 / span, V_PEAK / peak))

    def at(self, t):
        """(r mm, dr/dt mm/s)."""
        y = dy = 0.0
        if self.chirp is None:
            for amp, f, ph in self.tones:
                w = 2 * math.pi * f
                y += amp * math.sin(w * t + ph)
                dy += amp * w * math.cos(w * t + ph)
        else:
            amp, f0, ph = self.tones[0]
            k = (self.chirp - f0) / self.duration
            arg = 2 * math.pi * (f0 * t + 0.5 * k * t * t) + ph
            y = amp * math.sin(arg)
            dy = amp * math.cos(arg) * 2 * math.pi * (f0 + k * t)
        e, de = smoothstep(t, self.ramp)
        s = self.scale
        return self.centre + s * e * y, s * (e * dy + de * y)

    def describe(self):
        d = {"family": self.family, "centre_mm": round(self.centre, 4),
             "tones": [{"amp_mm": round(a * self.scale, 4), "freq_hz": round(f, 4),
                        "phase_rad": round(p, 4)} for a, f, p in self.tones]}
        if self.chirp is not None:
            d["chirp_end_hz"] = round(self.chirp, 4)
        return d


# --------------------------------------------------------------------------------------
# Trial design (shared by every catheter case of a seed)
# --------------------------------------------------------------------------------------
def design(seed, trials, duration):
    """Per-trial geometry, trajectory and nuisance draws, stratified over the trials."""
    plan = Stream(seed, "design")
    angle_slots = plan.permutation(trials)
    tube_slots = plan.permutation(trials)
    load_slots = plan.permutation(trials)
    fam_slots = plan.permutation(trials)
    out = []
    for i in range(trials):
        rng = Stream(seed, "trial", i)
        theta_deg = 90.0 + 270.0 * (angle_slots[i] + rng.unit()) / trials
        nb = 1 + rng.index(3)
        w = [rng.between(0.5, 1.5) for _ in range(nb)]
        bends = [{"angle_deg": round(theta_deg * x / sum(w), 3),
                  "radius_mm": round(rng.between(15.0, 60.0), 1)} for x in w]
        theta = sum(b["angle_deg"] for b in bends) * math.pi / 180.0
        sheath, wire = TUBES[tube_slots[i] % len(TUBES)]
        load = TIP_LOADS[load_slots[i] % len(TIP_LOADS)]
        ref = Reference(FAMILIES[fam_slots[i] % len(FAMILIES)], rng, duration)
        out.append({
            "geometry": {"sheath_id_mm": sheath, "guidewire_od_mm": wire, "bends": bends,
                         "tip_load_n": load},
            "theta": theta, "gap": round(sheath - wire, 6), "load": load, "ref": ref,
            "tip_offset": rng.between(-TIP_OFFSET, TIP_OFFSET),
            "band_pos": rng.between(-1.0, 1.0),    # initial tip in the deadzone band
            "bristle": rng.between(-1.0, 1.0),     # initial bristle deflection / z_ss
        })
    return out


# --------------------------------------------------------------------------------------
# The bench: servo base, LuGre friction, play-operator tip, sensors
# --------------------------------------------------------------------------------------
def simulate(trial, effects, duration, noise):
    """Returns the sample rows and the noise-free (effect, seed) channel pairs."""
    P = {name: EFFECTS[name]["parameters"] for name in effects}
    theta, gap, load, ref = trial["theta"], trial["gap"], trial["load"], trial["ref"]
    b0 = theta * gap
    g_seed = F0_N + MU_TIP * load
    n = int(round(duration * RATE_HZ))
    h = 1.0 / (RATE_HZ * SUB)
    wn = 2 * math.pi * SERVO_HZ
    kp, kd = wn * wn, 2 * SERVO_ZETA * wn

    ripple = P.get("ripple_friction")
    step = P.get("friction_step")
    warm = P.get("friction_warmup")
    bendv = P.get("bend_viscous")
    sback = P.get("speed_backlash")
    tipk = P.get("tip_speed_error")
    visc_eff = VISC + (bendv["c_n_per_mm_s_rad"] * theta if bendv else 0.0)
    t0_step = min(step["t0_s"], 0.5 * duration) if step else None

    x, v = ref.at(0.0)
    z = z_seed = trial["bristle"] * g_seed / SIGMA0
    tip = tip_seed = x + trial["band_pos"] * b0 / 2.0
    zdot = zdot_seed = 0.0
    tipv = 0.0
    rows = []
    clean = []  # (force, force_seed, tip, tip_seed) noise-free, offsets included
    peak_v = 0.0
    for i in range(n):
        t_i = i / RATE_HZ
        if i:
            for j in range(SUB):
                t = t_i - 1.0 / RATE_HZ + j * h
                r, dr = ref.at(t)
                v += h * (kp * (r - x) + kd * (dr - v))   # semi-implicit (symplectic) Euler
                x += h * v
                te = t + h
                av = abs(v)
                # friction level (effect) and seed level
                g = g_seed
                if ripple:
                    g += ripple["a_n"] * 0.5 * (1.0 + math.sin(
                        2 * math.pi * x / ripple["period_mm"] + ripple["phase_rad"]))
                if step and te >= t0_step:
                    g += step["delta_n"]
                scale = 1.0
                if warm:
                    scale = 1.0 + warm["a"] * (1.0 - math.exp(-te / warm["tau_s"]))
                g *= scale
                # LuGre bristle, implicit in z: z' = v - sigma0 |v| z / g
                zn = (z + h * v) / (1.0 + h * SIGMA0 * av / g)
                zdot, z = (zn - z) / h, zn
                zn = (z_seed + h * v) / (1.0 + h * SIGMA0 * av / g_seed)
                zdot_seed, z_seed = (zn - z_seed) / h, zn
                # play operator (deadzone) around the base
                half = 0.5 * b0 * (1.0 + av / sback["v0_mm_s"]) if sback else 0.5 * b0
                before = tip
                if tip < x - half:
                    tip = x - half
                elif tip > x + half:
                    tip = x + half
                tipv = (tip - before) / h
                if tip_seed < x - 0.5 * b0:
                    tip_seed = x - 0.5 * b0
                elif tip_seed > x + 0.5 * b0:
                    tip_seed = x + 0.5 * b0
            t_now = t_i
        else:
            t_now = 0.0
            scale = 1.0
        peak_v = max(peak_v, abs(v))
        force = SIGMA0 * z + SIGMA1 * zdot + visc_eff * scale * v
        force_seed = SIGMA0 * z_seed + SIGMA1 * zdot_seed + VISC * v
        tip_read = tip + trial["tip_offset"]
        if tipk:
            tip_read += tipk["k_mm_per_mm_s_sq"] * tipv * abs(tipv)
        tip_seed_read = tip_seed + trial["tip_offset"]
        r, _ = ref.at(t_now)
        f_meas = round((force + FORCE_SIGMA * noise.normal()) / FORCE_Q) * FORCE_Q
        y_meas = round((tip_read + TIP_SIGMA * noise.normal()) / TIP_Q) * TIP_Q
        b_meas = round(x / BASE_Q) * BASE_Q
        rows.append((t_now, r, b_meas, y_meas, f_meas))
        clean.append((force, force_seed, tip_read, tip_seed_read, v))
    return rows, clean, peak_v


def num(x, decimals):
    s = "%.*f" % (decimals, x)
    if s.startswith("-") and float(s) == 0.0:
        s = s[1:]
    return s


def solve(a, b):
    """Gaussian elimination with partial pivoting (small dense systems)."""
    n = len(b)
    m = [row[:] + [b[i]] for i, row in enumerate(a)]
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(m[r][c]))
        if abs(m[p][c]) < 1e-12:
            return None
        m[c], m[p] = m[p], m[c]
        for r in range(c + 1, n):
            f = m[r][c] / m[c][c]
            for k in range(c, n + 1):
                m[r][k] -= f * m[c][k]
    xs = [0.0] * n
    for c in range(n - 1, -1, -1):
        xs[c] = (m[c][n] - sum(m[c][k] * xs[k] for k in range(c + 1, n))) / m[c][c]
    return xs


def effect_size(trials_clean, plan, channels):
    """Raw RMS of each channel's effect (effect - seed physics, noise-free) and what is left
    after the part the seed model can absorb: force -> least squares on sign(v), sign(v)*N,
    v over moving samples (|v| > 2 mm/s); tip -> each trial's mean (the tip offset)."""
    out = {}
    for ch in channels:
        raw = 0.0
        cnt = 0
        left = 0.0
        if ch == "force":
            rows = []
            for clean, tr in zip(trials_clean, plan):
                for f, fs, _, _, v in clean:
                    if abs(v) > 2.0:
                        s = 1.0 if v > 0 else -1.0
                        rows.append(([s, s * tr["load"], v], f - fs))
            ata = [[sum(r[0][i] * r[0][j] for r in rows) for j in range(3)] for i in range(3)]
            atb = [sum(r[0][i] * r[1] for r in rows) for i in range(3)]
            coef = solve(ata, atb) or [0.0, 0.0, 0.0]
            for feat, y in rows:
                raw += y * y
                e = y - sum(c * q for c, q in zip(coef, feat))
                left += e * e
            cnt = len(rows)
            sigma, unit = FORCE_SIGMA, "n"
        else:
            for clean in trials_clean:
                d = [tp - ts for _, _, tp, ts, _ in clean]
                mean = sum(d) / len(d)
                raw += sum(e * e for e in d)
                left += sum((e - mean) ** 2 for e in d)
                cnt += len(d)
            sigma, unit = TIP_SIGMA, "mm"
        raw = math.sqrt(raw / max(cnt, 1))
        left = math.sqrt(left / max(cnt, 1))
        out[ch] = {"rms_" + unit: round(raw, 6), "noise_variances": round((raw / sigma) ** 2, 2),
                   "after_seed_absorbs_rms_" + unit: round(left, 6),
                   "after_seed_absorbs_noise_variances": round((left / sigma) ** 2, 2)}
    return out


def write_catheter_case(out, case, trials, duration, seed):
    effects = CATHETER_CASES[case]
    folder = os.path.join(out, case)
    os.makedirs(folder, exist_ok=True)
    plan = design(seed, trials, duration)
    cleans = []
    peak = 0.0
    for i, tr in enumerate(plan):
        noise = Stream(seed, case, "noise", i)
        rows, clean, pv = simulate(tr, effects, duration, noise)
        cleans.append(clean)
        peak = max(peak, pv)
        stem = os.path.join(folder, "trial_%03d" % i)
        doc = dict(tr["geometry"])
        doc["meta"] = {"generator": GENERATOR, "case": case, "seed": seed, "trial": i,
                       "trajectory": tr["ref"].describe(),
                       "total_bend_rad": round(tr["theta"], 6),
                       "deadzone_mm": round(tr["theta"] * tr["gap"], 6),
                       "tip_offset_mm": round(tr["tip_offset"], 6),
                       "peak_speed_mm_s": round(pv, 3)}
        with open(stem + ".json", "w") as f:
            json.dump(doc, f, indent=1)
            f.write("\n")
        with open(stem + ".csv", "w") as f:
            f.write("t,base_cmd,base,tip,force\n")
            f.write("".join("%s,%s,%s,%s,%s\n" % (num(t, 3), num(r, 6), num(b, 4), num(y, 2),
                                                   num(fo, 4))
                            for t, r, b, y, fo in rows))
    channels = sorted({EFFECTS[e]["channel"] for e in effects})
    size = effect_size(cleans, plan, channels) if effects else None
    eff = []
    for e in effects:
        spec = EFFECTS[e]
        p = dict(spec["parameters"])
        if e == "friction_step":
            p["t0_s"] = min(p["t0_s"], 0.5 * duration)
        eff.append({"name": e, "channel": spec["channel"], "variable": spec["variable"],
                    "variables": spec["variables"], "equation": spec["equation"],
                    "parameters": p})
    truth = {
        "kind": "catheter", "generator": GENERATOR, "case": case,
        "hidden_effect": "+".join(effects) if effects else None,
        "channel": eff[0]["channel"] if eff else None,
        "variable": eff[0]["variable"] if eff else None,
        "equation": " AND ".join(x["equation"] for x in eff) if eff else
                    "none: LuGre friction with g = f0 + mu_tip*N and sigma2*v, deadzone "
                    "B = theta*gap (seed physics only)",
        "parameters": {x["name"]: x["parameters"] for x in eff},
        "effects": eff,
        "noise": {"tip_mm": TIP_SIGMA, "force_n": FORCE_SIGMA},
        "seed": seed,
        "data": {
            "trials": trials, "duration_s": duration, "rate_hz": RATE_HZ,
            "quantum": {"tip_mm": TIP_Q, "force_n": FORCE_Q, "base_mm": BASE_Q},
            "seed_physics": {"coulomb_f0_n": F0_N, "mu_tip": MU_TIP,
                             "viscous_n_per_mm_s": VISC, "lugre_sigma0_n_per_mm": SIGMA0,
                             "lugre_sigma1_n_per_mm_s": SIGMA1,
                             "backlash": "B = theta * gap (play operator)",
                             "tip_offset_mm": "uniform in +-%g" % TIP_OFFSET},
            "integration": "semi-implicit Euler, %g ms steps" % (1000.0 / (RATE_HZ * SUB)),
            "base_servo": {"natural_hz": SERVO_HZ, "zeta": SERVO_ZETA},
            "peak_speed_mm_s": round(peak, 3),
            "effect_rms": size,
        },
    }
    with open(os.path.join(folder, "truth.json"), "w") as f:
        json.dump(truth, f, indent=2)
        f.write("\n")
    return truth


# --------------------------------------------------------------------------------------
# Heart motion traces
# --------------------------------------------------------------------------------------
def write_motion_case(out, case, seed, duration):
    heart = Stream(seed, "heart")          # the same heart in every motion case of a seed
    bpm = heart.between(60.0, 90.0)
    f0 = bpm / 60.0
    a1 = heart.between(3.5, 5.0)
    amps = [a1, a1 * heart.between(0.25, 0.4), a1 * heart.between(0.12, 0.2)]
    phases = [heart.between(0, 2 * math.pi) for _ in range(MOTION_HARMONICS)]
    c0 = heart.between(-3.0, 3.0)
    phi0 = heart.between(0, 2 * math.pi)
    rng = Stream(seed, case, "effect")
    noise = Stream(seed, case, "noise")
    spec = MOTION_EFFECTS[case]
    params = dict(spec["parameters"]) if spec else {}

    def beat(phi):
        return sum(a * math.cos((k + 1) * phi + p) for k, (a, p) in enumerate(zip(amps, phases)))

    if case == "motion_jump":
        params["t_jump_s"] = round(rng.between(0.35, 0.65) * duration, 4)
        params["jump_mm"] *= rng.sign()
    elif case in ("motion_rate_swing", "motion_amplitude_mod"):
        params["psi_rad"] = round(rng.between(0, 2 * math.pi), 4)
    elif case == "motion_beat_jitter":
        L0 = 1.0 / f0
        starts = [0.0]
        lengths = []
        while starts[-1] < duration + 2 * L0:
            lengths.append(L0 * (1.0 + rng.between(-params["e"], params["e"])))
            starts.append(starts[-1] + lengths[-1])
        # start mid-beat, so that the trace's first sample is at phase phi0 like the others
        shift = phi0 / (2 * math.pi) * lengths[0]

    n = int(round(duration * MOTION_HZ)) + 1
    rows = []
    sq = 0.0
    j = 0
    for i in range(n):
        t = i / MOTION_HZ
        phi = phi0 + 2 * math.pi * f0 * t
        x0 = c0 + beat(phi)
        x = x0
        if case == "motion_jump":
            if t >= params["t_jump_s"]:
                x += params["jump_mm"]
        elif case == "motion_rate_swing":
            df = params["swing_bpm"] / 60.0
            tr = params["period_s"]
            ps = params["psi_rad"]
            phi_s = phi - df * tr * (math.cos(2 * math.pi * t / tr + ps) - math.cos(ps))
            x = c0 + beat(phi_s)
        elif case == "motion_amplitude_mod":
            x = c0 + (1.0 + params["m"] * math.sin(2 * math.pi * t / params["period_s"]
                                                   + params["psi_rad"])) * beat(phi)
        elif case == "motion_beat_jitter":
            tt = t + shift
            while tt >= starts[j + 1]:
                j += 1
            x = c0 + beat(2 * math.pi * (j + (tt - starts[j]) / lengths[j]))
        sq += (x - x0) ** 2
        y = round((x + MOTION_SIGMA * noise.normal()) / MOTION_Q) * MOTION_Q
        rows.append((t, y, x))
    path = os.path.join(out, case + ".csv")
    with open(path, "w") as f:
        f.write("t,position,truth\n")
        f.write("".join("%s,%s,%s\n" % (num(t, 4), num(y, 2), num(x, 4)) for t, y, x in rows))
    rms = math.sqrt(sq / n)
    truth = {
        "kind": "motion", "generator": GENERATOR, "case": case, "trace": case + ".csv",
        "hidden_effect": case[len("motion_"):] if spec else None,
        "channel": "position" if spec else None,
        "variable": spec["variable"] if spec else None,
        "variables": spec["variables"] if spec else [],
        "equation": spec["equation"] if spec else
                    "none: x = c + sum_{k=1..3} A_k cos(k*phi + p_k), phi = phi0 + 2*pi*f0*t",
        "parameters": params,
        "model": "heartbeat:%d" % MOTION_HARMONICS,
        "noise": {"position_mm": MOTION_SIGMA},
        "seed": seed,
        "data": {
            "samples": n, "duration_s": duration, "rate_hz": MOTION_HZ,
            "quantum_mm": MOTION_Q, "heart_rate_bpm": round(bpm, 3),
            "harmonics_mm": [round(a, 4) for a in amps],
            "harmonic_phases_rad": [round(p, 4) for p in phases], "offset_mm": round(c0, 4),
            "effect_rms": ({"position": {"rms_mm": round(rms, 6),
                                         "noise_variances": round((rms / MOTION_SIGMA) ** 2, 2)}}
                           if spec else None),
        },
    }
    with open(os.path.join(out, case + ".truth.json"), "w") as f:
        json.dump(truth, f, indent=2)
        f.write("\n")
    return truth


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", help="output folder")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--case", action="append", choices=ALL_CASES,
                   help="case to write (repeatable); default: all")
    g.add_argument("--all", action="store_true", help="write every case (the default)")
    ap.add_argument("--trials", type=int, default=8, help="trials per catheter case (8)")
    ap.add_argument("--duration", type=float, default=4.0,
                    help="seconds per catheter trial (4)")
    ap.add_argument("--motion-duration", type=float, default=36.0,
                    help="seconds per motion trace (36)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    a = ap.parse_args(argv)
    if a.list:
        for name in ALL_CASES:
            if name in CATHETER_CASES:
                eff = CATHETER_CASES[name]
                chans = "+".join(EFFECTS[e]["channel"] for e in eff) or "-"
                print("%-22s catheter  %-32s %s" % (name, "+".join(eff) or "-", chans))
            else:
                print("%-22s motion    %-32s %s" % (name, name[7:] if MOTION_EFFECTS[name]
                                                    else "-",
                                                    "position" if MOTION_EFFECTS[name] else "-"))
        return 0
    if not a.out:
        ap.error("--out is required")
    if a.trials < 2:
        ap.error("--trials must be at least 2 (the lab cross-validates over trials)")
    if not 1.0 <= a.duration <= 600.0:
        ap.error("--duration must be in [1, 600] s")
    if not 10.0 <= a.motion_duration <= 600.0:
        ap.error("--motion-duration must be in [10, 600] s")
    os.makedirs(a.out, exist_ok=True)
    for name in a.case or ALL_CASES:
        if name in CATHETER_CASES:
            truth = write_catheter_case(a.out, name, a.trials, a.duration, a.seed)
        else:
            truth = write_motion_case(a.out, name, a.seed, a.motion_duration)
        size = truth["data"]["effect_rms"]
        desc = "; ".join("%s %s" % (ch, ", ".join("%s=%s" % kv for kv in d.items()))
                         for ch, d in (size or {}).items())
        print("%-22s %-32s %s" % (name, truth["hidden_effect"] or "none", desc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
