#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (-DECHOSERVO_FUZZ=ON, ASan + UBSan) into
# build-fuzz/ and runs each from its seed corpus (tests/fuzz/corpus/<name>) for a bounded
# time. Usage: scripts/fuzz.sh [SECONDS_PER_TARGET (default 25)] [TARGET...]
# libFuzzer runs one process per target on one core: the targets run side by side,
# ECHOSERVO_FUZZ_JOBS at a time (default: the number of cores), each for its full time.
# New inputs go to build-fuzz/corpus/<name> (the committed seeds are only read); a crash
# leaves build-fuzz/artifacts/<name>/crash-* and fails the script. Longer runs and the
# documented 10^6-execution run: docs/reliability.md "Sanitizers and fuzzing".
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
source scripts/lib/compiler.sh
source scripts/sanitizer_env.sh
# The targets write each input to a scratch file: keep those in memory when possible.
if [ -z "${TMPDIR:-}" ] && [ -d /dev/shm ] && [ -w /dev/shm ]; then export TMPDIR=/dev/shm; fi

seconds="${1:-25}"
shift || true
targets=("$@")
if [ "${#targets[@]}" -eq 0 ]; then
  targets=(igtl_message plus_sequence volume_io em_log trial_io dds_samples)
fi

cmake -S . -B build-fuzz -G Ninja \
  -DCMAKE_BUILD_TYPE=Release -DECHOSERVO_FUZZ=ON -DECHOSERVO_BUILD_TESTS=OFF \
  -DECHOSERVO_BUILD_BENCH=OFF
cmake --build build-fuzz -j2 --target fuzz_all

jobs="${ECHOSERVO_FUZZ_JOBS:-$(nproc)}"

# Runs one target; its log is build-fuzz/fuzz_<name>.log. Exit status: the fuzzer's.
run_target() {
  local t="$1"
  mkdir -p "build-fuzz/corpus/$t" "build-fuzz/artifacts/$t"
  build-fuzz/bin/fuzz_"$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
    -max_len=65536 -print_final_stats=1 -artifact_prefix="build-fuzz/artifacts/$t/" \
    "build-fuzz/corpus/$t" "tests/fuzz/corpus/$t" 2> "build-fuzz/fuzz_$t.log"
}

declare -A pids
failed=()
for t in "${targets[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$jobs" ]; do wait -n || true; done
  echo "fuzz: fuzz_$t for ${seconds} s"
  run_target "$t" &
  pids[$t]=$!
done
for t in "${targets[@]}"; do
  if ! wait "${pids[$t]}"; then failed+=("$t"); fi
done

for t in "${targets[@]}"; do
  echo "fuzz: fuzz_$t: $(grep -E '^stat::number_of_executed_units' "build-fuzz/fuzz_$t.log" || echo 'no stats')"
done
status=0
for t in "${failed[@]}"; do
  echo "fuzz: fuzz_$t FAILED (build-fuzz/fuzz_$t.log, build-fuzz/artifacts/$t/)" >&2
  tail -n 60 "build-fuzz/fuzz_$t.log" >&2
  status=1
done
exit "$status"
