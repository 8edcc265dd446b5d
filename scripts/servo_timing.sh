#!/usr/bin/env bash
# Builds and runs the servo timing comparison (bench/servo_timing_bench.cc): the 1 kHz
# servo loop as an ordinary thread and with SCHED_FIFO + locked memory (+ --servo-cpu N),
# under a load (default: the tracker on the simulated scanner), then cyclictest (rt-tests)
# as the floor, all in one session. Arguments go to the harness, e.g.
#   bash scripts/servo_timing.sh --seconds 60 --servo-cpu 3 --load tracker --json
# Run as root, or with RLIMIT_RTPRIO / RLIMIT_MEMLOCK raised (docs/control.md "Real-time
# execution"); install the packages first: bash scripts/setup.sh
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
source scripts/lib/compiler.sh

cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j2 --target echoservo_servo_timing_bench
echo "== $(date -u +%FT%TZ) $(nproc) CPUs, kernel $(uname -r) $(uname -v)"
./build/bin/echoservo_servo_timing_bench "$@"
