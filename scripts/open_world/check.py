#!/usr/bin/env python3
"""Checks `echoservo lab diagnose` against the open-world generator's ground truth.

  python3 scripts/open_world/check.py --echoservo PATH/TO/echoservo --data DIR
          [--case NAME ...] [--json-out FILE] [--apply] [--timeout S]

DIR is the output of scripts/open_world/generate.py: one folder per case with a catheter
dataset (trial_*.csv/.json) or a motion trace (trace.csv), and truth.json. For each case
it runs `echoservo lab diagnose DIR/<case> --model seed --json` (motion:
`DIR/<case>/trace.csv --model heartbeat:2`) and checks the issue's acceptance figures:

  null cases    : "verdict" == "adequate" and "adequate" is true;
  hidden effect : "verdict" == "unexplained" (and never adequate); the first `where`
                  entry of the truth channel names the truth variable; `proposal` exists
                  and its held-out error in the truth channel (force: proposal.force_rms_n,
                  tip: proposal.rms_mm, position: proposal.rms_mm) is at most 1.5x the
                  noise floor the JSON reports (noise.force_n / noise.tip_mm /
                  noise.position_mm).

--apply then re-runs `echoservo lab compare DIR/<case> --model <proposal.spec> --json`
and reports the truth channel's RMS against the noise (the tutorial's "watch the error
fall"); it fails the case if that RMS is above 1.5x the noise or the command fails.

Prints one table row per case and exits 1 on any failure (2 for a usage error). A missing
JSON key fails the case, naming the key. See docs/open_world_generator.md.
"""
import argparse
import json
import os
import subprocess
import sys

RMS_FACTOR = 1.5
# truth channel -> (proposal / compare key for the channel RMS, noise key)
CHANNEL_KEYS = {
    "force": ("force_rms_n", "force_n"),
    "tip": ("rms_mm", "tip_mm"),
    "position": ("rms_mm", "position_mm"),
}


class Missing(Exception):
    pass


def get(obj, path):
    """obj["a"]["b"]... for path "a.b"; raises Missing naming the key."""
    cur = obj
    done = []
    for key in path.split("."):
        done.append(key)
        if not isinstance(cur, dict) or key not in cur:
            raise Missing("missing key '%s'" % ".".join(done))
        cur = cur[key]
    return cur


def number(obj, path):
    v = get(obj, path)
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise Missing("key '%s' is not a number (%r)" % (path, v))
    return float(v)


def run_json(cmd, timeout):
    """Runs cmd; returns (json or None, error text or None, seconds)."""
    import time
    t0 = time.monotonic()
    try:
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                           timeout=timeout)
    except subprocess.TimeoutExpired:
        return None, "timed out after %g s: %s" % (timeout, " ".join(cmd)), timeout
    except OSError as e:
        return None, "cannot run %s: %s" % (cmd[0], e), 0.0
    dt = time.monotonic() - t0
    if p.returncode != 0:
        tail = (p.stderr.strip().splitlines() or [""])[-1]
        return None, "exit %d: %s" % (p.returncode, tail[:300]), dt
    text = p.stdout
    try:
        return json.loads(text), None, dt
    except ValueError:
        start = text.find("{")
        try:
            return json.loads(text[start:]), None, dt
        except ValueError as e:
            return None, "output is not JSON (%s)" % e, dt


def target_of(data, case, truth):
    if truth.get("kind") == "motion":
        return os.path.join(data, case, "trace.csv"), "heartbeat:2"
    return os.path.join(data, case), "seed"


def check_case(exe, data, case, timeout, apply):
    r = {"case": case, "pass": False, "reasons": []}
    truth_path = os.path.join(data, case, "truth.json")
    try:
        with open(truth_path) as f:
            truth = json.load(f)
    except (OSError, ValueError) as e:
        r["reasons"].append("cannot read %s: %s" % (truth_path, e))
        return r
    r["truth"] = {k: truth.get(k) for k in ("kind", "hidden_effect", "channel", "variable")}
    target, model = target_of(data, case, truth)
    cmd = [exe, "lab", "diagnose", target, "--model", model, "--json"]
    d, err, secs = run_json(cmd, timeout)
    r["seconds"] = round(secs, 2)
    if err:
        r["reasons"].append("diagnose: " + err)
        return r
    reasons = r["reasons"]

    def attempt(fn):
        try:
            return fn()
        except Missing as e:
            reasons.append(str(e))
            return None

    verdict = attempt(lambda: get(d, "verdict"))
    adequate = attempt(lambda: get(d, "adequate"))
    r["verdict"] = verdict
    r["adequate"] = adequate
    r["summary"] = d.get("summary")
    r["excess"] = d.get("excess")
    hidden = truth.get("hidden_effect")
    if hidden is None:
        if verdict is not None and verdict != "adequate":
            reasons.append("verdict '%s', expected 'adequate'" % verdict)
        if adequate is not None and adequate is not True:
            reasons.append("adequate is %r, expected true" % adequate)
    else:
        channel = truth.get("channel")
        variable = truth.get("variable")
        if verdict is not None and verdict != "unexplained":
            reasons.append("verdict '%s', expected 'unexplained'" % verdict)
        if adequate is True or verdict == "adequate":
            reasons.append("called adequate with a hidden effect (%s)" % hidden)
        where = attempt(lambda: get(d, "where"))
        if where is not None:
            if not isinstance(where, list):
                reasons.append("key 'where' is not a list")
            else:
                top = next((w for w in where if isinstance(w, dict)
                            and w.get("channel") == channel), None)
                if top is None:
                    reasons.append("no 'where' entry for channel '%s'" % channel)
                else:
                    r["where_top"] = {"variable": top.get("variable"),
                                      "explained_fraction": top.get("explained_fraction")}
                    if "variable" not in top:
                        reasons.append("missing key 'where[].variable'")
                    elif top["variable"] != variable:
                        reasons.append("top %s variable '%s', expected '%s'"
                                       % (channel, top["variable"], variable))
        rms_key, noise_key = CHANNEL_KEYS.get(channel, (None, None))
        if rms_key is None:
            reasons.append("truth.json: unknown channel %r" % channel)
        else:
            proposal = attempt(lambda: get(d, "proposal"))
            noise = attempt(lambda: number(d, "noise." + noise_key))
            if isinstance(proposal, dict):
                r["proposal"] = {k: proposal.get(k) for k in ("spec", "file", "equation")}
                rms = attempt(lambda: number(d, "proposal." + rms_key))
                if rms is not None and noise is not None:
                    r["channel_rms"] = rms
                    r["noise"] = noise
                    r["ratio"] = rms / noise if noise > 0 else float("inf")
                    if not rms <= RMS_FACTOR * noise:
                        reasons.append("proposal held-out %s rms %.4g > %.1fx noise %.4g"
                                       % (channel, rms, RMS_FACTOR, noise))
                if apply:
                    spec = proposal.get("spec")
                    if not spec:
                        reasons.append("missing key 'proposal.spec' (for --apply)")
                    else:
                        apply_case(exe, target, spec, channel, timeout, r)
            elif proposal is not None:
                reasons.append("key 'proposal' is not an object")
    r["pass"] = not reasons
    return r


def apply_case(exe, target, spec, channel, timeout, r):
    cmd = [exe, "lab", "compare", target, "--model", spec, "--json"]
    c, err, secs = run_json(cmd, timeout)
    a = {"spec": spec, "seconds": round(secs, 2)}
    r["apply"] = a
    if err:
        r["reasons"].append("apply: " + err)
        return
    rms_key, noise_key = CHANNEL_KEYS[channel]
    try:
        rms = number(c, rms_key)
        if isinstance(c.get("noise"), dict):
            noise = number(c, "noise." + noise_key)
        else:
            noise = number(c, "noise_mm")  # motion compare before the per-channel noise object
    except Missing as e:
        r["reasons"].append("apply: " + str(e))
        return
    a.update({"channel_rms": rms, "noise": noise, "ratio": rms / noise if noise > 0 else None})
    if not rms <= RMS_FACTOR * noise:
        r["reasons"].append("apply: %s rms %.4g > %.1fx noise %.4g"
                            % (channel, rms, RMS_FACTOR, noise))


def fmt_num(x, spec="%.3g"):
    return "-" if x is None else (spec % x if isinstance(x, (int, float)) else str(x))


def print_table(results, apply):
    head = ["case", "verdict", "top where (explained)", "proposal", "rms/noise"]
    if apply:
        head.append("applied rms/noise")
    head.append("result")
    rows = []
    for r in results:
        wt = r.get("where_top")
        where = "-" if not wt else "%s (%s)" % (wt.get("variable"),
                                                fmt_num(wt.get("explained_fraction"), "%.2f"))
        prop = r.get("proposal") or {}
        eq = prop.get("equation") or prop.get("spec") or "-"
        if len(eq) > 44:
            eq = eq[:41] + "..."
        ratio = "-"
        if "channel_rms" in r:
            ratio = "%.4g/%.4g=%.2f" % (r["channel_rms"], r["noise"], r["ratio"])
        verdict = str(r.get("verdict"))
        if len(verdict) > 24:
            verdict = verdict[:21] + "..."
        row = [r["case"], verdict, where, eq, ratio]
        if apply:
            a = r.get("apply") or {}
            row.append("%.4g/%.4g=%.2f" % (a["channel_rms"], a["noise"], a["ratio"])
                       if a.get("ratio") is not None else "-")
        row.append("PASS" if r["pass"] else "FAIL")
        rows.append(row)
    widths = [max(len(h), *(len(x[i]) for x in rows)) if rows else len(h)
              for i, h in enumerate(head)]
    line = "  ".join(h.ljust(w) for h, w in zip(head, widths))
    print(line)
    print("-" * len(line))
    for row in rows:
        print("  ".join(c.ljust(w) for c, w in zip(row, widths)))
    for r in results:
        for why in r["reasons"]:
            print("%s: FAIL: %s" % (r["case"], why))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--echoservo", required=True, help="path to the echoservo binary")
    ap.add_argument("--data", required=True, help="folder written by generate.py")
    ap.add_argument("--case", action="append", help="case to check (repeatable; default all)")
    ap.add_argument("--json-out", help="write the per-case results as JSON here")
    ap.add_argument("--apply", action="store_true",
                    help="re-run lab compare with each proposal's spec and report its RMS")
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per command (900)")
    a = ap.parse_args(argv)
    if not os.path.isfile(a.echoservo):
        ap.error("no echoservo binary at %s" % a.echoservo)
    if a.case:
        cases = a.case
    else:
        try:
            cases = sorted(n for n in os.listdir(a.data)
                           if os.path.isfile(os.path.join(a.data, n, "truth.json")))
        except OSError as e:
            ap.error("cannot list %s: %s" % (a.data, e))
        if not cases:
            ap.error("no case (a folder with truth.json) in %s" % a.data)
        # catheter cases first, each group's null case first
        cases.sort(key=lambda n: (n.startswith("motion"), n not in ("null", "motion_null"), n))
    results = []
    for case in cases:
        r = check_case(a.echoservo, a.data, case, a.timeout, a.apply)
        results.append(r)
        sys.stderr.write("%s: %s (%.1f s)\n" % (case, "PASS" if r["pass"] else "FAIL",
                                                  r.get("seconds", 0.0)))
    print_table(results, a.apply)
    failed = [r["case"] for r in results if not r["pass"]]
    print("\n%d/%d cases pass%s" % (len(results) - len(failed), len(results),
                                   "" if not failed else "; failed: " + ", ".join(failed)))
    if a.json_out:
        with open(a.json_out, "w") as f:
            json.dump({"cases": results, "passed": not failed}, f, indent=2)
            f.write("\n")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
