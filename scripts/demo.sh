#!/usr/bin/env bash
# Builds echoservo (as scripts/test.sh does) and runs the seed's tip-tracking experiment
# on the simulated catheter along the mitral annulus trajectory with each backlash
# compensation in turn: none, iterative (the seed's offline method), adaptive (online).
# Install the packages first: bash scripts/setup.sh
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build -j2

for compensation in none iterative adaptive; do
  echo
  echo "== echoservo sim track --trajectory mitral --compensation ${compensation}"
  ./build/bin/echoservo sim track --trajectory mitral --compensation "${compensation}"
done
