# ECHOSERVO_LINKER (default: lld when the compiler can use it, else the compiler's default):
# the linker for every executable and shared library. LLVM's lld links the test executables
# (each a dozen static project libraries plus VTK, Fast DDS and Ceres) several times faster
# than GNU ld, which matters for the two full builds CI makes (docs/reliability.md "CI time").
# -DECHOSERVO_LINKER=default keeps the compiler's own choice; any other value is passed as
# -fuse-ld=<value> (e.g. gold).
include(CheckLinkerFlag)
set(ECHOSERVO_LINKER "" CACHE STRING "Linker passed as -fuse-ld (empty: lld if usable)")
if(ECHOSERVO_LINKER STREQUAL "")
  check_linker_flag(CXX "-fuse-ld=lld" ECHOSERVO_HAVE_LLD)
  if(ECHOSERVO_HAVE_LLD)
    add_link_options(-fuse-ld=lld)
  endif()
elseif(NOT ECHOSERVO_LINKER STREQUAL "default")
  # One cached result per linker name, so that changing ECHOSERVO_LINKER checks again.
  check_linker_flag(CXX "-fuse-ld=${ECHOSERVO_LINKER}" ECHOSERVO_LINKER_${ECHOSERVO_LINKER}_WORKS)
  if(NOT ECHOSERVO_LINKER_${ECHOSERVO_LINKER}_WORKS)
    message(FATAL_ERROR "ECHOSERVO_LINKER=${ECHOSERVO_LINKER}: the compiler cannot link with "
                        "-fuse-ld=${ECHOSERVO_LINKER}")
  endif()
  add_link_options(-fuse-ld=${ECHOSERVO_LINKER})
endif()
