#!/usr/bin/env bash
# Builds echoservo (as scripts/test.sh does) and runs the seed's tip-tracking experiment
# on the simulated catheter (1 Hz sine and mitral annulus trajectories) with every
# backlash compensation: none, static inverse, iterative (the seed's offline method)
# and adaptive (online), printed beside the seed's published figures.
# Install the packages first: bash scripts/setup.sh
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build -j2

echo
echo "== echoservo sim track --trajectory all --compensation all"
./build/bin/echoservo sim track --trajectory all --compensation all
