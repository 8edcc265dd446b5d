#!/usr/bin/env bash
# Builds everything except the benchmarks with AddressSanitizer + UndefinedBehaviorSanitizer
# (-DECHOSERVO_SANITIZE=ON, GCC, -O1) into build-asan/ and runs the whole test suite under
# them with CTest (docs/reliability.md "Sanitizers and fuzzing"). Exits non-zero when the
# build or any test fails, or a sanitizer reports anything (UBSan does not recover).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
source scripts/sanitizer_env.sh

cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=Release -DECHOSERVO_SANITIZE=ON \
  -DECHOSERVO_BUILD_BENCH=OFF
cmake --build build-asan -j2
ctest --test-dir build-asan --output-on-failure -j2
