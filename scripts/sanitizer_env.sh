# Sourced by scripts/test_sanitize.sh and scripts/fuzz.sh: run-time options of the
# sanitizers (they also reach the test binaries run at build time by gtest discovery, and
# the `echoservo` processes the CLI tests start). Suppression files: tests/sanitizers/.
_sanitizer_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/tests/sanitizers"
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:detect_stack_use_after_return=0:strict_init_order=1${ASAN_OPTIONS:+:$ASAN_OPTIONS}"
export LSAN_OPTIONS="suppressions=${_sanitizer_dir}/lsan.supp:print_suppressions=0${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:suppressions=${_sanitizer_dir}/ubsan.supp${UBSAN_OPTIONS:+:$UBSAN_OPTIONS}"
unset _sanitizer_dir
