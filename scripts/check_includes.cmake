# Fails when a source of a target includes a header of the project that lies outside the directories the target's
# layer may read: the layer rules of docs/ARCHITECTURE.md, checked at build time (occgeo_enforce_layer in the top-level
# CMakeLists.txt makes every layered target depend on this check, so a wrong-way include does not build).
#
#   cmake -DTARGET=name -DFILES=a.cc;b.h -DINCLUDE_ROOTS=d1;d2 -DALLOWED=d1;d2 -DPROJECT_DIR=dir [-DSTAMP=file]
#     -P check_includes.cmake
#
# An `#include "x"` resolves as the compiler does it: next to the including file first, then in each include root. A
# header found inside PROJECT_DIR but under none of ALLOWED is an error naming the file, the line and the header.
# Headers found nowhere (generated ones in the build tree, system headers) are not the check's business.
cmake_minimum_required(VERSION 3.25)

foreach(required TARGET FILES ALLOWED PROJECT_DIR)
  if(NOT DEFINED ${required})
    message(FATAL_ERROR "check_includes.cmake: -D${required}=... is required")
  endif()
endforeach()

# Lists arrive joined with '|' (a ';' would split the command line).
foreach(list_var FILES ALLOWED INCLUDE_ROOTS)
  string(REPLACE "|" ";" ${list_var} "${${list_var}}")
endforeach()

set(errors "")
foreach(file IN LISTS FILES)
  if(NOT EXISTS "${file}")
    continue()
  endif()
  get_filename_component(file_dir "${file}" DIRECTORY)
  file(STRINGS "${file}" lines REGEX "^[ \t]*#[ \t]*include[ \t]*\"")
  foreach(line IN LISTS lines)
    string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*\"([^\"]+)\".*" "\\1" header "${line}")
    set(found "")
    foreach(root IN LISTS file_dir INCLUDE_ROOTS)
      if(EXISTS "${root}/${header}" AND NOT IS_DIRECTORY "${root}/${header}")
        get_filename_component(found "${root}/${header}" ABSOLUTE)
        break()
      endif()
    endforeach()
    if(found STREQUAL "")
      continue()
    endif()
    string(FIND "${found}" "${PROJECT_DIR}/" in_project)
    if(NOT in_project EQUAL 0)
      continue()
    endif()
    set(allowed_here FALSE)
    foreach(dir IN LISTS ALLOWED)
      string(FIND "${found}" "${dir}/" under)
      if(under EQUAL 0)
        set(allowed_here TRUE)
        break()
      endif()
    endforeach()
    if(NOT allowed_here)
      file(RELATIVE_PATH file_rel "${PROJECT_DIR}" "${file}")
      file(RELATIVE_PATH header_rel "${PROJECT_DIR}" "${found}")
      string(APPEND errors "  ${file_rel} includes ${header_rel}, a header of a layer above ${TARGET} or beside it\n")
    endif()
  endforeach()
endforeach()

if(NOT errors STREQUAL "")
  set(allowed_rel "")
  foreach(dir IN LISTS ALLOWED)
    file(RELATIVE_PATH rel "${PROJECT_DIR}" "${dir}")
    list(APPEND allowed_rel "${rel}/")
  endforeach()
  list(JOIN allowed_rel ", " allowed_text)
  message(FATAL_ERROR "layer rule broken:\n${errors}${TARGET} may include headers from: ${allowed_text}\n"
                      "(see docs/ARCHITECTURE.md, Layers)")
endif()
if(DEFINED STAMP)
  file(TOUCH "${STAMP}")
endif()
