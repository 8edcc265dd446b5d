# Sourced by the build scripts (test.sh, demo.sh, test_sanitize.sh, fuzz.sh): every build
# they configure uses clang 14 unless CC / CXX name another compiler (docs/reliability.md
# "CI time"). CMake reads them only when it creates a build folder, which keeps its first
# compiler.
export CC="${CC:-clang-14}" CXX="${CXX:-clang++-14}"
