# Sourced by scripts/test_sanitize.sh and scripts/fuzz.sh: run-time options of the
# sanitizers (they also reach the test binaries run at build time by gtest discovery, and
# the `echoservo` processes the CLI tests start). Suppression files: tests/sanitizers/.
_sanitizer_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/tests/sanitizers"
# new_delete_type_mismatch=0: Fast DDS 2.9.1 (Debian's libfastrtps, not instrumented) allocates
# a StatisticsReaderImpl (64 bytes) and deletes it as its 56-byte base in
# RTPSReader::~RTPSReader — both frames inside libfastrtps.so, on every DataReader deletion,
# so every test that closes a DDS subscriber aborted. ASan cannot suppress that check per
# library, so it is off for the whole sanitizer run (docs/reliability.md).
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:detect_stack_use_after_return=0:strict_init_order=1:new_delete_type_mismatch=0${ASAN_OPTIONS:+:$ASAN_OPTIONS}"
export LSAN_OPTIONS="suppressions=${_sanitizer_dir}/lsan.supp:print_suppressions=0${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:suppressions=${_sanitizer_dir}/ubsan.supp${UBSAN_OPTIONS:+:$UBSAN_OPTIONS}"
unset _sanitizer_dir
