# cmake -DSOURCE_DIR=<repo> -DTABLE=<build>/architecture-includes.txt -P SakerCheckIncludes.cmake
#
# Every `#include "core/<x>/..."` or `#include "ui/..."` in a library's folder must name that
# folder or one of the folders listed after it in TABLE (cmake/SakerArchitecture.cmake writes it
# from the link graph). Prints each offending include as file:line and fails.
cmake_minimum_required(VERSION 3.25)
file(STRINGS ${TABLE} rows)
set(violations 0)
foreach(row IN LISTS rows)
  string(REPLACE " " ";" folders "${row}")
  list(GET folders 0 folder)
  file(GLOB_RECURSE sources ${SOURCE_DIR}/${folder}/*.h ${SOURCE_DIR}/${folder}/*.cc)
  foreach(source IN LISTS sources)
    file(STRINGS ${source} includes REGEX "^#include \"(core|ui)/")
    foreach(include IN LISTS includes)
      string(REGEX REPLACE "^#include \"((core/[a-z_]+)|ui)/.*$" "\\1" included "${include}")
      if(NOT included IN_LIST folders)
        file(RELATIVE_PATH rel ${SOURCE_DIR} ${source})
        message(SEND_ERROR "${rel}: ${include}: ${folder} does not link ${included}")
        math(EXPR violations "${violations} + 1")
      endif()
    endforeach()
  endforeach()
endforeach()
if(violations GREATER 0)
  message(FATAL_ERROR "${violations} include(s) against the layers of docs/architecture.md")
endif()
list(LENGTH rows libraries)
message(STATUS "architecture: the includes of ${libraries} libraries follow their links")
