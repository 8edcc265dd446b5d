#!/usr/bin/env bash
# Builds everything except the benchmarks with AddressSanitizer + UndefinedBehaviorSanitizer
# (-DECHOSERVO_SANITIZE=ON, -O1) into build-asan/ and runs the whole test suite under them
# with CTest (docs/reliability.md "Sanitizers and fuzzing"). Exits non-zero when the build
# or any test fails, or a sanitizer reports anything (UBSan does not recover).
# Compiler: clang 14 by default (its UBSan also checks pointer overflow, vptr and function
# types, and found a pointer overflow GCC's did not; build and suite take as long as with
# GCC). CC=gcc CXX=g++ selects GCC 12 (use a fresh build folder, e.g. BUILD=build-asan-gcc).
# --build-only / --test-only: one of the two phases (.ci/run times them as two stages).
# The echoservo program and the suites that run it are left out (their end-to-end tests run
# in the Release suite; CI time, docs/reliability.md): ECHOSERVO_SANITIZE_CLI=ON builds and
# runs them too.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
source scripts/lib/compiler.sh
source scripts/sanitizer_env.sh
phase="${1:-all}"
case "$phase" in all | --build-only | --test-only) ;; *)
  echo "usage: scripts/test_sanitize.sh [--build-only|--test-only]" >&2
  exit 2
  ;;
esac

build="${BUILD:-build-asan}"
if [[ "$phase" != --test-only ]]; then
  cmake -S . -B "$build" -G Ninja \
    -DCMAKE_BUILD_TYPE=Release -DECHOSERVO_SANITIZE=ON -DECHOSERVO_BUILD_BENCH=OFF \
    -DECHOSERVO_SANITIZE_CLI="${ECHOSERVO_SANITIZE_CLI:-OFF}"
  cmake --build "$build" -j2
fi
if [[ "$phase" != --build-only ]]; then
  ctest --test-dir "$build" --output-on-failure -j2
fi
