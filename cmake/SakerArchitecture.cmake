# The layer rules of docs/architecture.md, checked from the targets themselves.
#
# saker_check_architecture(), once every library is defined:
#  - fails the configuration when an engine library, or the GUI library, links the simulator
#    (saker_sim) directly or through another library: only saker_eval, the CLI, the tests and the
#    benchmarks may, so that the engine never depends on how its test videos are made;
#  - writes ${PROJECT_BINARY_DIR}/architecture-includes.txt, one line per library: its folder,
#    then the folders whose headers it may include (its own and those of every library it links,
#    directly or not). The test `architecture/includes` (cmake/SakerCheckIncludes.cmake) holds every
#    `#include "core/..."` and `#include "ui/..."` of the sources to it, so an include that the
#    link graph does not back (an upward include) fails the suite.

# Every saker_* library `target` links, directly or through others (PUBLIC and PRIVATE).
function(saker_link_closure target out_var)
  set(seen "")
  set(stack ${target})
  while(stack)
    list(POP_FRONT stack current)
    get_target_property(libs ${current} LINK_LIBRARIES)
    if(NOT libs)
      continue()
    endif()
    foreach(lib IN LISTS libs)
      if(lib MATCHES "^saker_" AND TARGET ${lib} AND NOT lib STREQUAL "saker_compile_options"
         AND NOT lib IN_LIST seen)
        list(APPEND seen ${lib})
        list(APPEND stack ${lib})
      endif()
    endforeach()
  endwhile()
  set(${out_var} ${seen} PARENT_SCOPE)
endfunction()

function(_saker_folder_of target out_var)
  get_target_property(dir ${target} SOURCE_DIR)
  file(RELATIVE_PATH rel ${PROJECT_SOURCE_DIR} ${dir})
  set(${out_var} ${rel} PARENT_SCOPE)
endfunction()

function(saker_check_architecture)
  get_property(libraries GLOBAL PROPERTY SAKER_LIBRARIES)
  if(TARGET saker_ui)
    list(APPEND libraries saker_ui)
  endif()
  set(lines "")
  foreach(lib IN LISTS libraries)
    saker_link_closure(${lib} closure)
    if(NOT lib STREQUAL "saker_sim" AND NOT lib STREQUAL "saker_eval" AND "saker_sim" IN_LIST closure)
      message(FATAL_ERROR "${lib} links the simulator (saker_sim): only saker_eval, the CLI, the "
                          "tests and the benchmarks may (docs/architecture.md)")
    endif()
    _saker_folder_of(${lib} folder)
    set(line "${folder}")
    foreach(dep IN LISTS closure)
      _saker_folder_of(${dep} dep_folder)
      string(APPEND line " ${dep_folder}")
    endforeach()
    string(APPEND lines "${line}\n")
  endforeach()
  file(WRITE ${PROJECT_BINARY_DIR}/architecture-includes.txt "${lines}")
endfunction()
