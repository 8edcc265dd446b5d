# Build-wide instrumentation options (docs/reliability.md, "Sanitizers and fuzzing").
#
# ECHOSERVO_SANITIZE: every target of the project (libraries, tests, the CLI, generated
# DDS types) is compiled and linked with AddressSanitizer and UndefinedBehaviorSanitizer.
# UBSan does not recover (-fno-sanitize-recover=all): the first report aborts the process,
# so a test that triggers one fails. Optimisation is -O1 (overrides the build type's -O)
# with frame pointers and line tables (-g1), for symbolised stacks at a modest slow-down
# and compile time; hot kernels -O2, most test executables -O0 (the functions below).
# System libraries (Fast DDS, VTK, Embree, TBB, Ceres, OpenCV) are not instrumented; ASan
# still checks every access made from our code. Run-time options and suppressions: tests/sanitizers/.
#
# ECHOSERVO_FUZZ: libFuzzer targets (tests/fuzz, build/bin/fuzz_*) with clang. The
# project's code is compiled with -fsanitize=fuzzer-no-link (coverage) plus ASan and UBSan;
# only the fuzz executables link the libFuzzer driver. Build them with
# `cmake --build build-fuzz --target fuzz_all` (builds nothing they do not need).
option(ECHOSERVO_SANITIZE "Build everything with AddressSanitizer and UndefinedBehaviorSanitizer" OFF)
# ECHOSERVO_SANITIZE_CLI: also build the echoservo program and the test suites that run it
# under the sanitizers (off: the libraries and their suites only; tests/CMakeLists.txt).
option(ECHOSERVO_SANITIZE_CLI "With ECHOSERVO_SANITIZE: also the program and its CLI suites" OFF)
option(ECHOSERVO_FUZZ "Build the libFuzzer targets (clang only)" OFF)

set(ECHOSERVO_SANITIZER_FLAGS
  -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)

if(ECHOSERVO_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    message(FATAL_ERROR "ECHOSERVO_FUZZ needs clang (libFuzzer), e.g. "
      "CC=clang-14 CXX=clang++-14 cmake -S . -B build-fuzz -DECHOSERVO_FUZZ=ON")
  endif()
  include(CheckCXXSourceCompiles)
  set(CMAKE_REQUIRED_FLAGS "-fsanitize=fuzzer")
  check_cxx_source_compiles([[
    #include <cstddef>
    #include <cstdint>
    extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t*, std::size_t) { return 0; }
  ]] ECHOSERVO_HAVE_LIBFUZZER)
  unset(CMAKE_REQUIRED_FLAGS)
  if(NOT ECHOSERVO_HAVE_LIBFUZZER)
    message(FATAL_ERROR "-fsanitize=fuzzer does not link with ${CMAKE_CXX_COMPILER} "
      "(Debian: apt-get install clang-14 libclang-rt-14-dev)")
  endif()
  add_compile_options(${ECHOSERVO_SANITIZER_FLAGS} -g1 -O1 -fsanitize=fuzzer-no-link)
  add_link_options(-fsanitize=address,undefined)
elseif(ECHOSERVO_SANITIZE)
  add_compile_options(${ECHOSERVO_SANITIZER_FLAGS} -O1 -g1)
  # For the few tests that must know (GCC defines __SANITIZE_ADDRESS__, clang does not).
  add_compile_definitions(ECHOSERVO_SANITIZED=1)
  add_link_options(-fsanitize=address,undefined -fno-sanitize-recover=all)
endif()

# GCC warns falsely under ASan at -O1 (its manual advises against -Werror with sanitizers):
# -Wmaybe-uninitialized inside std::regex's std::function states. Targets that use
# std::regex call this; it does nothing outside GCC sanitizer builds.
function(echoservo_sanitizer_warning_exceptions target)
  if(ECHOSERVO_SANITIZE AND CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    target_compile_options(${target} PRIVATE -Wno-maybe-uninitialized)
  endif()
endfunction()

# echoservo_sanitizer_hot_sources(FILE ...): the numeric kernels that dominate the sanitizer
# suite's run time (found with perf; docs/reliability.md "CI time") compile at -O2 in the
# sanitizer build instead of -O1. They stay fully instrumented by ASan and UBSan; -O2 inlines
# their small helpers and vectorises their loops as Release does. A source with its own
# options leaves its unity batch. Call it in the directory that lists the sources.
function(echoservo_sanitizer_hot_sources)
  if(ECHOSERVO_SANITIZE)
    set_source_files_properties(${ARGN} PROPERTIES COMPILE_OPTIONS -O2)
  endif()
endfunction()

# echoservo_sanitizer_test_target(TARGET): a GoogleTest executable compiles at -O0 in the
# sanitizer build (instead of -O1), still fully instrumented. Test files are the bulk of
# that build (assertion macros, fixtures, GoogleTest's templates) and most of them only
# drive the libraries or start processes; -O0 halves their compile time. Not for tests that
# compute in process (echoservo_test(... COMPUTE)): the linker keeps the test file's copy
# of an inline function the libraries also use (the test's objects come first), so -O0
# copies of Eigen and standard-library templates would slow the libraries' hot loops too
# (the detector tests ran up to 2.6x longer; docs/reliability.md "CI time").
function(echoservo_sanitizer_test_target target)
  if(ECHOSERVO_SANITIZE)
    target_compile_options(${target} PRIVATE -O0)
  endif()
endfunction()
