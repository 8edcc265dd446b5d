#!/usr/bin/env bash
# Live-path speed against a base commit, side by side in one session (docs/benchmarks.md
# "perf_compare"): builds BASE_REF and the working tree in separate Release build folders,
# then runs, alternating base and head (ABBA order), `echoservo bench detect`, the OpenIGTLink
# ingest bench and a 20 s `echoservo demo`, and prints each figure with the ratio head/base.
#
#   scripts/perf_compare.sh BASE_REF [--reps N] [--demo-seconds S] [--volumes-per-class N]
#                                    [--out DIR] [--head-build DIR] [--build-only]
#
# The working tree is never modified: the base's sources are exported with `git archive` into
# OUT/base-SHA/src and built in OUT/base-SHA/build (both reused when present); the head builds
# from the working tree into build/ (the README's Release build; --head-build DIR for another).
# OUT (default build-perf/) also holds every run's raw output and summary.txt.
# Not part of CI (minutes of machine time). Exit status: 0, or 2 for bad arguments, 3 for a ref
# that does not exist, 4 for a step that failed (the message names the ref and the step).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
source scripts/lib/compiler.sh

usage() {
  echo "usage: scripts/perf_compare.sh BASE_REF [--reps N] [--demo-seconds S]" \
    "[--volumes-per-class N] [--out DIR] [--head-build DIR] [--build-only]" >&2
  exit 2
}
[[ $# -ge 1 ]] || usage
base_ref="$1"
shift
reps=2
demo_s=20
vpc=3
out=build-perf
head_build=build
build_only=0
while [[ $# -gt 0 ]]; do
  case "$1" in
    --reps) reps="${2:-}"; shift 2 ;;
    --demo-seconds) demo_s="${2:-}"; shift 2 ;;
    --volumes-per-class) vpc="${2:-}"; shift 2 ;;
    --out) out="${2:-}"; shift 2 ;;
    --head-build) head_build="${2:-}"; shift 2 ;;
    --build-only) build_only=1; shift ;;
    *) usage ;;
  esac
done
for n in "$reps" "$demo_s" "$vpc"; do
  [[ "$n" =~ ^[1-9][0-9]*$ ]] || {
    echo "perf_compare: '$n' is not a positive integer" >&2
    exit 2
  }
done

fail() {  # step, log
  echo "perf_compare: $1 failed${2:+ (log: $2)}" >&2
  [[ -n "${2:-}" && -f "$2" ]] && tail -n 20 "$2" >&2
  exit 4
}

sha=$(git rev-parse --verify --quiet "${base_ref}^{commit}") || {
  echo "perf_compare: ref '${base_ref}' does not exist in this repository" \
    "(git rev-parse --verify '${base_ref}^{commit}')" >&2
  exit 3
}
short=${sha:0:12}
mkdir -p "$out"
out=$(cd "$out" && pwd)
base_dir="$out/base-$short"
runs="$out/runs-$(date +%Y%m%d-%H%M%S)"
mkdir -p "$runs"
echo "perf_compare: base ${base_ref} = ${short}, head = working tree of $(git rev-parse --short HEAD)" \
  "$(git diff --quiet HEAD && echo '(clean)' || echo '(with uncommitted changes)')"

if [[ ! -f "$base_dir/src/CMakeLists.txt" ]]; then
  rm -rf "$base_dir/src"
  mkdir -p "$base_dir/src"
  git archive "$sha" | tar -x -C "$base_dir/src" ||
    fail "ref '${base_ref}' (${short}): exporting its sources (git archive)"
  # Data that travels beside the repository (../shared) is reached the same way by both.
fi

build() {  # name, source dir, build dir
  local log="$runs/build-$1.log"
  echo "perf_compare: building $1 in $3"
  if [[ -f "$3/CMakeCache.txt" ]]; then  # an existing build keeps its configuration
    grep -q "CMAKE_BUILD_TYPE:STRING=Release" "$3/CMakeCache.txt" ||
      fail "$1 (${4}): $3 is not a Release build" ""
    : >"$log"
  else
    cmake -S "$2" -B "$3" -G Ninja -DCMAKE_BUILD_TYPE=Release -DECHOSERVO_BUILD_TESTS=OFF \
      >"$log" 2>&1 || fail "$1 (${4}): configure" "$log"
  fi
  cmake --build "$3" -j2 --target echoservo echoservo_ingest_bench >>"$log" 2>&1 ||
    fail "$1 (${4}): build" "$log"
}
build base "$base_dir/src" "$base_dir/build" "ref '${base_ref}' = ${short}"
build head "$PWD" "$head_build" "working tree"
head_bin="$(cd "$head_build" && pwd)/bin"
if ((build_only)); then
  echo "perf_compare: built base in $base_dir/build, head in $head_build"
  exit 0
fi

# One round of every figure for one build; outputs go to runs/NAME-REP.*.
round() {  # name, bin dir, rep
  local name="$1" bin="$2" rep="$3" tag="$runs/$1-$3"
  echo "perf_compare: round $rep, $name"
  "$bin/echoservo" bench detect --volumes-per-class "$vpc" --json >"$tag.detect.json" 2>"$tag.detect.err" || fail "$name: bench detect" "$tag.detect.err"
  "$bin/echoservo_ingest_bench" 300 >"$tag.ingest.txt" 2>&1 || fail "$name: ingest bench" "$tag.ingest.txt"
  "$bin/echoservo" demo --duration "$demo_s" --seed "$rep" --json >"$tag.demo.json" \
    2>"$tag.demo.err" || fail "$name: demo" "$tag.demo.err"
}
for ((r = 1; r <= reps; ++r)); do
  if ((r % 2)); then
    round base "$base_dir/build/bin" "$r"
    round head "$head_bin" "$r"
  else
    round head "$head_bin" "$r"
    round base "$base_dir/build/bin" "$r"
  fi
done
python3 scripts/perf_compare_summary.py "$runs" "$reps" | tee "$runs/summary.txt"
echo "perf_compare: raw outputs and summary in $runs"
