#!/usr/bin/env python3
"""Error budget of an `echoservo demo --out RUN` directory against its truth.csv (usage: scripts/run_error_budget.py RUN [--from S]).

Axis coordinates s = p . a (image frame, mm), a = the true catheter axis (the tip's
direction of travel in truth.csv). Everything from --from (3 s) on.
  det_tip   : detected tip  - true tip at acquisition       (per volume)
  det_tgt   : detected target - true target at acquisition  (per volume)
  det_diff  : det_tgt - det_tip: what the follower's reference actually depends on
  total     : true tip - desired tip (true target - standoff)  (100 Hz)
  servo     : k*(tip - setpoint), catheter mm scaled to image mm (k = image/catheter scale)
  reference : total - servo (the reference's own error, image mm)
  ref_lp/hp : reference error split at ~0.5 Hz (1 s moving mean): offset vs prediction
"""
import csv, math, sys, json

def rd(path):
    with open(path) as f:
        return list(csv.DictReader(f))

def stats(xs):
    n = len(xs)
    if n == 0:
        return dict(n=0)
    m = sum(xs) / n
    sd = math.sqrt(sum((x - m) ** 2 for x in xs) / n)
    rms = math.sqrt(sum(x * x for x in xs) / n)
    return dict(n=n, mean=round(m, 3), sd=round(sd, 3), rms=round(rms, 3))

def interp(ts, vs, t):
    # ts sorted, uniform-ish
    lo, hi = 0, len(ts) - 1
    if t <= ts[0]: return vs[0]
    if t >= ts[-1]: return vs[-1]
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if ts[mid] <= t: lo = mid
        else: hi = mid
    f = (t - ts[lo]) / (ts[hi] - ts[lo])
    return [a + f * (b - a) for a, b in zip(vs[lo], vs[hi])] if isinstance(vs[0], list) else vs[lo] + f * (vs[hi] - vs[lo])

def main(run, t_from=3.0, standoff=None):
    info = json.load(open(run + "/run.json"))
    if standoff is None:
        standoff = info.get("standoff_mm", 8.0)
    truth = rd(run + "/truth.csv")
    T = [float(r["t_s"]) for r in truth]
    tgt = [[float(r["target_%s_mm" % c]) for c in "xyz"] for r in truth]
    tip = [[float(r["tip_%s_mm" % c]) for c in "xyz"] for r in truth]
    # axis: direction of tip travel (largest excursion)
    i0 = min(range(len(tip)), key=lambda i: tip[i][0]); i1 = max(range(len(tip)), key=lambda i: tip[i][0])
    d = [tip[i1][c] - tip[i0][c] for c in range(3)]
    nd = math.sqrt(sum(x * x for x in d)); a = [x / nd for x in d]
    dot = lambda p: sum(p[c] * a[c] for c in range(3))
    s_tip = [dot(p) for p in tip]; s_tgt = [dot(p) for p in tgt]
    servo = rd(run + "/servo.csv")
    ST = [float(r["t_s"]) for r in servo]
    sp = [float(r["setpoint_mm"]) for r in servo]
    xt = [float(r["tip_estimate_mm"]) for r in servo]
    # scale k: true image s vs catheter x (regression over the run)
    xs = [interp(ST, xt, t) for t in T]
    mx = sum(xs) / len(xs); ms = sum(s_tip) / len(s_tip)
    k = sum((x - mx) * (s - ms) for x, s in zip(xs, s_tip)) / max(1e-12, sum((x - mx) ** 2 for x in xs))
    tot, sv, ref, mode_ok = [], [], [], []
    perp = []
    for i, t in enumerate(T):
        if t < t_from: continue
        e = s_tip[i] - (s_tgt[i] - standoff)
        j = min(range(max(0, i - 2), min(len(ST), i + 3)), key=lambda j: abs(ST[j] - t))
        es = k * (xs[i] - sp[j])
        tot.append(e); sv.append(es); ref.append(e - es)
        pv = [tip[i][c] - (tgt[i][c] - standoff * a[c]) for c in range(3)]
        perp.append(math.sqrt(max(0.0, sum(x * x for x in pv) - e * e)))
    # 1 s moving mean of the reference error
    w = 50
    lp = [sum(ref[max(0, i - w):i + w + 1]) / len(ref[max(0, i - w):i + w + 1]) for i in range(len(ref))]
    hp = [r - l for r, l in zip(ref, lp)]
    # target excursion and the scale term
    stg = [s for t, s in zip(T, s_tgt) if t >= t_from]
    mt = sum(stg) / len(stg)
    scale_term = [(k - 1.0) * (s - mt) for s in stg]
    targets = rd(run + "/targets.csv")
    dtip, dtgt, ddiff = [], [], []
    for r in targets:
        if r["found"] != "1": continue
        t = float(r["acquired_s"])
        if t < t_from: continue
        p_tip = [float(r["tip_%s_mm" % c]) for c in "xyz"]
        p_tgt = [float(r["target_%s_mm" % c]) for c in "xyz"]
        et = dot(p_tip) - interp(T, s_tip, t)
        eg = dot(p_tgt) - interp(T, s_tgt, t)
        dtip.append(et); dtgt.append(eg); ddiff.append(eg - et)
    out = dict(run=run, k_image_per_catheter=round(k, 4),
               total=stats(tot), perp_rms=stats(perp)["rms"], servo=stats(sv), reference=stats(ref),
               ref_lowpass=stats(lp), ref_highpass=stats(hp), scale_term=stats(scale_term),
               det_tip=stats(dtip), det_target=stats(dtgt), det_target_minus_tip=stats(ddiff))
    return out

if __name__ == "__main__":
    for run in sys.argv[1:]:
        o = main(run)
        print(o["run"], "k=%.4f" % o["k_image_per_catheter"], "perp_rms", o["perp_rms"])
        for key in ["total", "servo", "reference", "ref_lowpass", "ref_highpass", "scale_term", "det_tip", "det_target", "det_target_minus_tip"]:
            print("  %-22s %s" % (key, o[key]))
