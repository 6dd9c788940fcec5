# Preprocesses a one-line file with the include path one engine library's own sources get
# (-E only: quick): that library's own header must be found, and no header of a later stage
# may be: a backward include does not compile.
#   cmake -DCXX=compiler -DINCLUDES="dir|dir|..." -DOWN=stage/x.h -DLATER="stage/y.h|..." -DWORK=dir
#         -P check_includes.cmake
string(REPLACE "|" ";" includes "${INCLUDES}")
set(flags)
foreach(dir IN LISTS includes)
  list(APPEND flags "-I${dir}")
endforeach()
file(MAKE_DIRECTORY "${WORK}")

function(preprocess header rc_var err_var)
  file(WRITE "${WORK}/probe.cpp" "#include \"${header}\"\n")
  execute_process(COMMAND ${CXX} -std=c++20 -E ${flags} "${WORK}/probe.cpp" -o "${WORK}/probe.ii"
                  RESULT_VARIABLE rc ERROR_VARIABLE err OUTPUT_QUIET)
  set(${rc_var} "${rc}" PARENT_SCOPE)
  set(${err_var} "${err}" PARENT_SCOPE)
endfunction()

preprocess("${OWN}" rc err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the library's own header ${OWN} is not reachable:\n${err}")
endif()

string(REPLACE "|" ";" later "${LATER}")
set(count 0)
foreach(header IN LISTS later)
  preprocess("${header}" rc err)
  if(rc EQUAL 0)
    message(FATAL_ERROR "${header}, a later stage's header, is reachable from this library: its include path leaks")
  endif()
  # GCC: "render/renderer.h: No such file or directory"; Clang: "'render/renderer.h' file not found".
  string(REGEX MATCH "${header}.? *(: No such file or directory|file not found)" missing "${err}")
  if(NOT missing)
    message(FATAL_ERROR "${header} failed for another reason than not being found:\n${err}")
  endif()
  math(EXPR count "${count} + 1")
endforeach()
message(STATUS "${OWN} found; the headers of ${count} later stages are out of reach")
