# echoservo_module(NAME SOURCES ... PUBLIC_DEPS ... PRIVATE_DEPS ...): one library per
# module folder, with the namespaced alias echoservo::NAME and the project's warning policy.
#
# ECHOSERVO_UNITY (default ON): every project target compiles its sources in unity batches
# of ECHOSERVO_UNITY_BATCH files, so header-only libraries that are compiled in every file
# (CLI11, nlohmann_json, GoogleTest, Eigen) are compiled once per batch instead of once per
# file (docs/reliability.md "CI time"). File-local names must therefore be unique within a
# target; -DECHOSERVO_UNITY=OFF builds file by file.
option(ECHOSERVO_UNITY "Compile each target in unity batches" ON)
set(ECHOSERVO_UNITY_BATCH 8 CACHE STRING "Files per unity batch (ECHOSERVO_UNITY)")

function(echoservo_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Werror -Wpedantic)
  # GCC 12's -Wrestrict fires inside libstdc++'s std::string concatenation inlined at -O3
  # (GCC bug 105651, fixed in GCC 13): a false positive in the standard library, kept a
  # warning for GCC.
  target_compile_options(${target} PRIVATE $<$<CXX_COMPILER_ID:GNU>:-Wno-error=restrict>)
endfunction()

# Applies the unity policy to one of the project's targets.
function(echoservo_unity target)
  set_target_properties(${target} PROPERTIES
    UNITY_BUILD ${ECHOSERVO_UNITY} UNITY_BUILD_BATCH_SIZE ${ECHOSERVO_UNITY_BATCH})
endfunction()

function(echoservo_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(echoservo_${name} STATIC ${ARG_SOURCES})
  add_library(echoservo::${name} ALIAS echoservo_${name})
  target_include_directories(echoservo_${name} PUBLIC ${PROJECT_SOURCE_DIR})
  target_link_libraries(echoservo_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  echoservo_warnings(echoservo_${name})
  echoservo_unity(echoservo_${name})
endfunction()
