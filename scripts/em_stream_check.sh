#!/usr/bin/env bash
# The "EM in" figure of issue 19: a PLUS-like server (tests/imaging/plus_like_server.cc,
# libOpenIGTLink only) streams one tool at 40 Hz for SECONDS s, each pose sent twice (PLUS's
# resends) beside a second tool, to `echoservo track --sim --em-connect`; then RUN/em.csv is
# checked against what the peer sent: every pose once, none duplicated, times strictly
# increasing, positions equal to float32 precision.
#
# usage: scripts/em_stream_check.sh [BUILD_DIR] [SECONDS] [RATE_HZ]
#   BUILD_DIR  with bin/echoservo and bin/plus_like_server (default: build)
#   SECONDS    the peer's streaming time (default 60); track runs SECONDS + 2 s
# Prints the figures as one JSON line; exit status 1 when a check fails.
set -euo pipefail
build=${1:-build}
seconds=${2:-60}
rate=${3:-40}
work=$(mktemp -d /tmp/em_stream_check.XXXXXX)
trap 'kill "${peer_pid:-}" 2>/dev/null || true' EXIT

"$build/bin/plus_like_server" --port 0 --rate "$rate" --duration "$seconds" --resend \
  --other-tool ProbeToTracker --sent "$work/sent.csv" >"$work/peer.out" 2>"$work/peer.err" &
peer_pid=$!
port=""
for _ in $(seq 100); do
  port=$(sed -n 's/^port \([0-9]*\)$/\1/p' "$work/peer.out" 2>/dev/null | head -1)
  [[ -n "$port" ]] && break
  sleep 0.05
done
[[ -n "$port" ]] || { echo "em_stream_check: the peer did not start: $(cat "$work/peer.err")" >&2; exit 1; }

"$build/bin/echoservo" track --sim --duration "$((seconds + 2))" \
  --em-connect "127.0.0.1:$port" --em-tool CatheterTipToTracker \
  --out "$work/run" --json >"$work/track.json" 2>"$work/track.err"
wait "$peer_pid"
peer_pid=""

python3 - "$work" <<'PY'
import csv, json, sys
work = sys.argv[1]
def rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))
sent = rows(f"{work}/sent.csv")
em = rows(f"{work}/run/em.csv")
stream = json.load(open(f"{work}/run/em_stream.json"))
t_sent = [float(r["t_s"]) for r in sent]
t_em = [float(r["t_s"]) for r in em]
increasing = all(b > a for a, b in zip(t_em, t_em[1:]))
duplicates = len(t_em) - len(set(t_em))
missing = sorted(set(t_sent) - set(t_em))
extra = sorted(set(t_em) - set(t_sent))
by_t = {float(r["t_s"]): r for r in sent}
max_dev = 0.0
for r in em:
    s = by_t.get(float(r["t_s"]))
    if s:
        max_dev = max(max_dev, max(abs(float(r[k]) - float(s[k])) for k in ("x_mm", "y_mm", "z_mm")))
span = t_em[-1] - t_em[0] if len(t_em) > 1 else 0.0
out = {
    "sent": len(sent), "em_rows": len(em), "missing": len(missing), "extra": len(extra),
    "duplicates": duplicates, "strictly_increasing": increasing,
    "max_position_deviation_mm": max_dev, "span_s": span,
    "rate_hz": (len(t_em) - 1) / span if span > 0 else 0.0,
    "client": {k: stream[k] for k in ("samples", "valid_samples", "duplicates_skipped",
                                      "older_skipped", "rejected_by_reason", "connections",
                                      "disconnects")},
    "work_dir": work,
}
print(json.dumps(out))
ok = (len(sent) > 0 and len(em) == len(sent) and not missing and not extra and duplicates == 0
      and increasing and max_dev < 1e-3)
sys.exit(0 if ok else 1)
PY
