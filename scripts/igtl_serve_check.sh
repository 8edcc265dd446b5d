#!/usr/bin/env bash
# `echoservo demo --igtl-serve` end to end with OpenIGTLink clients that share no code with
# echoservo (Python sockets, the header parsed by hand and each body's CRC-64 ECMA-182
# checked): two clients read every message, a third connects and never reads. Checks that the
# readers got every TRANSFORM the server counts as sent, in order, with acquisition stamps
# that increase and lie within 1 s before their receipt; then runs the same demo without a
# server and prints both runs' tracker latency (p50/p99) side by side (two processes, one
# after the other: bench/igtl_serve_bench.cc is the same-process comparison).
# Usage: scripts/igtl_serve_check.sh [BUILD_DIR] [DURATION_S] [--igtl-volumes]
set -euo pipefail
build=${1:-build}
duration=${2:-15}
extra=${3:-}
bin="$build/bin/echoservo"
port=$((20000 + RANDOM % 20000))
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

"$bin" demo --duration "$duration" --seed 1 --igtl-serve "$port" $extra --json \
  >"$tmp/serve.json" 2>"$tmp/serve.log" &
demo=$!
python3 - "$port" "$duration" "$tmp/clients.json" <<'PY'
import json, socket, struct, sys, threading, time
port, duration, out = int(sys.argv[1]), float(sys.argv[2]), sys.argv[3]
POLY = 0x42F0E1EBA9EA3693
TABLE = []
for i in range(256):
    c = i << 56
    for _ in range(8):
        c = ((c << 1) ^ POLY) if c & (1 << 63) else (c << 1)
    TABLE.append(c & 0xFFFFFFFFFFFFFFFF)
def crc64(data):
    c = 0
    for b in data:
        c = TABLE[((c >> 56) ^ b) & 0xFF] ^ ((c << 8) & 0xFFFFFFFFFFFFFFFF)
    return c
def connect():
    end = time.time() + 20
    while True:
        try:
            return socket.create_connection(("127.0.0.1", port), timeout=2)
        except OSError:
            if time.time() > end: raise
            time.sleep(0.1)
def recv_exact(s, n):
    buf = bytearray()
    while len(buf) < n:
        chunk = s.recv(n - len(buf))
        if not chunk: return None
        buf += chunk
    return bytes(buf)
results = []
def reader():
    s = connect(); s.settimeout(duration + 30)
    r = {"types": {}, "transform_stamps": [], "bad_crc": 0, "late_or_future": 0}
    while True:
        h = recv_exact(s, 58)
        if h is None: break
        _, typ, dev, ts, size, crc = struct.unpack(">H12s20sQQQ", h)
        body = recv_exact(s, size)
        if body is None: break
        now = time.time()
        typ = typ.rstrip(b"\0").decode()
        # The IMAGE CRC in pure Python is slow: checked on small messages only.
        if size < 100000 and crc64(body) != crc: r["bad_crc"] += 1
        r["types"][typ] = r["types"].get(typ, 0) + 1
        if typ == "TRANSFORM":
            t = (ts >> 32) + (ts & 0xFFFFFFFF) / 2**32
            r["transform_stamps"].append(t)
            if not (now - 1.0 <= t <= now + 0.01): r["late_or_future"] += 1
    results.append(r)
stalled = connect()  # never reads
threads = [threading.Thread(target=reader) for _ in range(2)]
for t in threads: t.start()
for t in threads: t.join()
stalled.close()
for r in results:
    st = r.pop("transform_stamps")
    r["transforms"] = len(st)
    r["stamps_increasing"] = all(b > a for a, b in zip(st, st[1:]))
json.dump(results, open(out, "w"))
PY
wait "$demo"
"$bin" demo --duration "$duration" --seed 1 --json >"$tmp/base.json" 2>/dev/null
python3 - "$tmp/serve.json" "$tmp/base.json" "$tmp/clients.json" <<'PY'
import json, sys
serve, base, clients = (json.load(open(p)) for p in sys.argv[1:4])
srv = serve["igtl_serve"]
ok = True
for i, c in enumerate(clients):
    print(f"reader {i}: {c}")
    ok &= c["bad_crc"] == 0 and c["stamps_increasing"] and c["late_or_future"] == 0
ok &= len(clients) == 2
total = sum(c["transforms"] for c in clients)
print("server:", {k: srv[k] for k in ("samples_published", "sent", "messages_dropped",
      "clients_accepted", "clients_stalled", "clients_disconnected", "send_latency_ms_p99")})
print(f"TRANSFORMs received by the readers: {total}")
# Every TRANSFORM reached both readers: the server counts one per client that got it whole,
# and the stalled client got at most as many as a reader.
per_reader = [c["transforms"] for c in clients]
ok &= per_reader[0] == per_reader[1] and 2 * per_reader[0] <= srv["sent"]["TRANSFORM"] <= 3 * per_reader[0]
for name, r in (("with server, 3 clients (1 stalled)", serve), ("without server", base)):
    print(f"{name}: latency p50 {r['latency_ms']['p50']:.1f} ms, p99 {r['latency_ms']['p99']:.1f} ms, "
          f"detected {r['detected']}/{r['volumes']}, EM RMS {r['tip_to_target_rms_mm']:.3f} mm")
ok &= srv["messages_dropped"] == sum(x["messages_dropped"] for x in srv["clients"])
print("OK" if ok else "FAILED")
sys.exit(0 if ok else 1)
PY
