#!/usr/bin/env bash
# The live pipeline across two "hosts" on one machine: `echoservo servo` in network
# namespace es_live_b (10.78.0.2) and `echoservo track --sim` in es_live_a (10.78.0.1),
# joined by a veth pair, UDP only (--no-shm: namespaces share /dev/shm, hosts do not), with
# interface whitelists and unicast initial peers (no multicast needed). The tracker's
# simulated scanner follows the tip the servo reports over the link, so the loop closes
# across the "hosts". Prints both JSON summaries. Optional impairment of the veth (both
# ways): NETEM="delay 2ms 1ms loss 1%" (tc netem, where the kernel has it), or
# TBF="rate 120kbit burst 2kb latency 20ms" (a token-bucket bottleneck: packets over the
# rate queue up to `latency`, then drop — delay and loss from congestion; tc tbf is in
# kernels without netem). With OUT=DIR the summaries are also left in DIR
# (track.json, servo.json). TRACK_ARGS="..." adds options to `track` (e.g. "--rate 12
# --harmonics 3" for a slow build). Needs root and iproute2; removes what it made on exit.
# Usage: scripts/live_two_namespaces.sh [build/bin/echoservo] [track seconds]
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
cli=$(realpath "${1:-build/bin/echoservo}")
seconds=${2:-10}
a=es_live_a b=es_live_b

source scripts/lib/two_namespaces.sh
two_namespaces "$a" "$b" es_live_va es_live_vb 10.78.0
if [[ -n "${NETEM:-}" ]]; then
  ip netns exec "$a" tc qdisc add dev es_live_va root netem $NETEM
  ip netns exec "$b" tc qdisc add dev es_live_vb root netem $NETEM
fi
if [[ -n "${TBF:-}" ]]; then
  ip netns exec "$a" tc qdisc add dev es_live_va root tbf $TBF
  ip netns exec "$b" tc qdisc add dev es_live_vb root tbf $TBF
fi

out=$(mktemp -d)
link_b="--dds-domain 7 --no-shm --interface 10.78.0.2 --peer 10.78.0.1"
link_a="--dds-domain 7 --no-shm --interface 10.78.0.1 --peer 10.78.0.2"
ip netns exec "$b" timeout $((seconds + 30)) "$cli" servo $link_b --auto-enable --duration $((seconds + 4)) --json \
  >"$out/servo.json" 2>"$out/servo.err" &
servo_pid=$!
ip netns exec "$a" timeout $((seconds + 30)) "$cli" track --sim $link_a ${TRACK_ARGS:-} --duration "$seconds" --json \
  >"$out/track.json" 2>"$out/track.err"
wait "$servo_pid"
if [[ -n "${NETEM:-}${TBF:-}" ]]; then
  echo "== veth es_live_va (namespace $a) queue: $(ip netns exec "$a" tc -s qdisc show dev es_live_va | tr '\n' ' ')"
  echo "== veth es_live_vb (namespace $b) queue: $(ip netns exec "$b" tc -s qdisc show dev es_live_vb | tr '\n' ' ')"
fi
echo "== track (namespace $a)"
cat "$out/track.json"
echo "== servo (namespace $b)"
cat "$out/servo.json"
if [[ -n "${OUT:-}" ]]; then cp "$out"/*.json "$OUT"/; fi
rm -rf "$out"
