# Runs one ctest command with the checks ctest alone cannot combine (tests/CMakeLists.txt,
# attekf_add_checked_test):
#   cmake -DCMD=<command;args...> [-DPROGRAMS=<path;...>] [-DPYTHON=<python>]
#         [-DPY_MODULES=<module;...>] [-DPASS_LINE=<regex>] -P RunTest.cmake
#   cmake -DSCRIPT=<file.cmake> [-D<its variables>...] [-DPROGRAMS=...] -P RunTest.cmake
# - CMD: a program and its arguments; SCRIPT: a CMake script run in this process after the
#   checks (its variables come as -D, so that lists among them need no second level of quoting).
# - PROGRAMS / PY_MODULES: what the command needs. A missing one fails the test under CI=true
#   (scripts/setup.sh installs everything there, so it is a broken set-up) and otherwise prints
#   "ATTEKF-SKIP: <reason>", which the test's SKIP_REGULAR_EXPRESSION turns into a visible skip.
# - The command must exit 0, and with PASS_LINE its output must also contain a line matching
#   it (ctest's PASS_REGULAR_EXPRESSION alone would ignore the exit status).
cmake_minimum_required(VERSION 3.20)

function(missing reason)
  string(TOLOWER "$ENV{CI}" ci)
  if(ci STREQUAL "1" OR ci STREQUAL "true" OR ci STREQUAL "yes")
    message(FATAL_ERROR "FAILED: ${reason} (CI=true: a missing tool fails the run; "
                        "scripts/setup.sh installs it)")
  endif()
  message(NOTICE "ATTEKF-SKIP: ${reason} (scripts/setup.sh installs it)")
endfunction()

if(NOT CMD AND NOT SCRIPT)
  message(FATAL_ERROR "RunTest.cmake: no command (-DCMD=...) and no script (-DSCRIPT=...)")
endif()
foreach(prog IN LISTS PROGRAMS)
  if(NOT prog OR prog MATCHES "-NOTFOUND$" OR NOT EXISTS "${prog}")
    missing("program not found: ${prog}")
    return()
  endif()
endforeach()
foreach(mod IN LISTS PY_MODULES)
  if(NOT PYTHON OR NOT EXISTS "${PYTHON}")
    missing("Python interpreter not found: '${PYTHON}'")
    return()
  endif()
  execute_process(COMMAND "${PYTHON}" -c "import ${mod}" RESULT_VARIABLE rc OUTPUT_QUIET ERROR_QUIET)
  if(NOT rc EQUAL 0)
    missing("Python module '${mod}' cannot be imported by ${PYTHON}")
    return()
  endif()
endforeach()

if(SCRIPT)
  include("${SCRIPT}")
  return()
endif()
if(PASS_LINE)
  execute_process(COMMAND ${CMD} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
  message(NOTICE "${out}")
else()
  execute_process(COMMAND ${CMD} RESULT_VARIABLE rc)
endif()
if(NOT rc STREQUAL "0")
  message(FATAL_ERROR "FAILED: exit status ${rc} of: ${CMD}")
endif()
if(PASS_LINE AND NOT out MATCHES "${PASS_LINE}")
  message(FATAL_ERROR "FAILED: exit status 0 but no line matching '${PASS_LINE}' in the output")
endif()
