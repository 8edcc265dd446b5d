#!/usr/bin/env bash
# Builds echoservo (as scripts/test.sh does) and runs the main job: the closed-loop demo on
# the embedded simulated scanner and catheter — volumes at 25 vol/s with a 50–100 ms imaging
# delay → Radon catheter detector → heartbeat EKF → DDS → 1 kHz servo on the simulated
# catheter, measured by a simulated EM tracker, with its accuracy report and the zero-order-
# hold baseline run in the same process — and
# the seed's tip-tracking experiment (every backlash compensation) beside its published
# figures. Install the packages first: bash scripts/setup.sh
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
source scripts/lib/compiler.sh

cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build -j2

echo
echo "== echoservo demo --duration 20 --out runs/demo --baseline"
rm -rf runs/demo
./build/bin/echoservo demo --duration 20 --out runs/demo --baseline
echo "(the demo wrote its report: runs/demo/report.html; echoservo report runs/demo --from 3 --out ... rewrites it)"
echo
echo "== echoservo sim track --trajectory all --compensation all"
./build/bin/echoservo sim track --trajectory all --compensation all
