# echoservo_module(NAME SOURCES ... DEPS ...): one library per module folder,
# with the namespaced alias echoservo::NAME and the project's warning policy.
function(echoservo_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Werror -Wpedantic)
endfunction()

function(echoservo_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(echoservo_${name} STATIC ${ARG_SOURCES})
  add_library(echoservo::${name} ALIAS echoservo_${name})
  target_include_directories(echoservo_${name} PUBLIC ${PROJECT_SOURCE_DIR})
  target_link_libraries(echoservo_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  echoservo_warnings(echoservo_${name})
endfunction()
