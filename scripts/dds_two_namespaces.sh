#!/usr/bin/env bash
# Two "hosts" on one machine: network namespaces es_dds_a (10.77.0.1) and es_dds_b
# (10.77.0.2) joined by a veth pair, each with only its veth and loopback. Runs the DDS
# bench's subscriber in b and its publisher in a, UDP only (--no-shm: namespaces share
# /dev/shm, hosts do not), once with the default discovery (multicast over the veth) and
# once with an interface whitelist and unicast initial peers (networks without
# multicast). Prints the subscriber's latency table and the bytes that crossed the veth.
# Needs root and iproute2; removes what it made on exit. Usage:
#   scripts/dds_two_namespaces.sh [build/bin/echoservo_dds_bench] [samples]
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bench=$(realpath "${1:-build/bin/echoservo_dds_bench}")
samples=${2:-2000}
a=es_dds_a b=es_dds_b

source scripts/lib/two_namespaces.sh
two_namespaces "$a" "$b" es_dds_va es_dds_vb 10.77.0

tx_bytes() { ip -n "$a" -s link show es_dds_va | awk 'f{print $1; exit} /TX:/{f=1}'; }

run() {  # name domain sub-args pub-args
  local name=$1 domain=$2 sub_args=$3 pub_args=$4 before out
  before=$(tx_bytes)
  out=$(mktemp)
  ip netns exec "$b" timeout 90 "$bench" --subscriber --domain "$domain" --samples "$samples" \
    --transport default --no-shm $sub_args >"$out" 2>&1 &
  local sub=$!
  sleep 1
  ip netns exec "$a" timeout 90 "$bench" --publisher --domain "$domain" --samples "$samples" \
    --rate 1000 --transport default --no-shm $pub_args
  wait "$sub" || true
  echo "== $name: $(( $(tx_bytes) - before )) bytes a→b over the veth"
  cat "$out"
  rm -f "$out"
}

run "multicast discovery" 77 "" ""
run "interface whitelist + unicast initial peers" 78 \
  "--interface 10.77.0.2 --peer 10.77.0.1" "--interface 10.77.0.1 --peer 10.77.0.2"
