# The file list of docs/porting.md ("Building without CMake"), generated from the CMake
# source lists so that it stays what CMake builds:
#   cmake -DLISTS=<lists.cmake> -DMODE=check|update [-DCC=<compiler> -DOUT=<dir>] -P PortingDoc.cmake
# LISTS sets ROOT, CORE_SOURCES, IEEE_SOURCES, FIXED_SOURCES, CORE_INCLUDES, PUBLIC_HEADERS, MODELS_SOURCES,
# MODELS_INCLUDES, MODELS_HEADERS and WARNINGS (tests/consumer/register.cmake writes it from
# firmware/CMakeLists.txt's variables; ctest porting_doc_current runs MODE=check,
# cmake --build build/host --target porting-doc runs MODE=update).
#
# check: the block between the markers in docs/porting.md must equal the generated one; then
# the documented files are copied into one directory and built with the documented command
# line (and the project's warnings as errors), for each scalar type, with a main that aligns
# and steps the filter.
cmake_minimum_required(VERSION 3.21)
include("${CMAKE_CURRENT_LIST_DIR}/HeaderClosure.cmake")
if(NOT DEFINED LISTS OR NOT DEFINED MODE)
  message(FATAL_ERROR "PortingDoc.cmake: -DLISTS=... and -DMODE=check|update needed")
endif()
include("${LISTS}")
set(doc "${ROOT}/docs/porting.md")
set(begin_marker "<!-- BEGIN FILES: generated from the CMake source lists (cmake --build build/host --target porting-doc) -->")
set(end_marker "<!-- END FILES -->")
# The documented command lines (the check runs them as written, with CC for cc).
set(cmd_float "cc -std=c99 -O2 -DEKF_SCALAR_FLOAT=1 -Iattekf -o app main.c attekf/*.c -lm")

attekf_header_closure(core_headers FILES ${CORE_SOURCES} ${IEEE_SOURCES} ${FIXED_SOURCES} DIRS ${CORE_INCLUDES})
attekf_header_closure(models_headers FILES ${MODELS_SOURCES} DIRS ${MODELS_INCLUDES})

function(rel_list out)
  set(text "")
  foreach(f IN LISTS ARGN)
    file(RELATIVE_PATH r "${ROOT}" "${f}")
    string(APPEND text "    ${r}\n")
  endforeach()
  set(${out} "${text}" PARENT_SCOPE)
endfunction()
set(private_headers ${core_headers})
list(REMOVE_ITEM private_headers ${PUBLIC_HEADERS})
rel_list(t_sources ${CORE_SOURCES})
rel_list(t_ieee ${IEEE_SOURCES})
rel_list(t_fixed ${FIXED_SOURCES})
rel_list(t_public ${PUBLIC_HEADERS})
rel_list(t_private ${private_headers})
rel_list(t_msources ${MODELS_SOURCES})
rel_list(t_mheaders ${models_headers})

set(block "${begin_marker}
Sources, every scalar type:

${t_sources}
And those of your scalar type: float (`EKF_SCALAR_FLOAT`) or double (`EKF_SCALAR_DOUBLE`),

${t_ieee}
or fixed point (`EKF_SCALAR_FIXED`),

${t_fixed}
Public headers (what your code includes; CMake installs these to `include/attekf/`):

${t_public}
Internal headers (needed to compile the sources):

${t_private}
Optional, the model library (`docs/models.md`), on top of the above:

${t_msources}${t_mheaders}
Copy them into one directory (`attekf/` below; the includes are by file name) and build
with the scalar type defined on every compile line (a source of the other scalar types stops
the build with an `#error` that names the right ones):

```sh
${cmd_float}
```

${end_marker}")

file(READ "${doc}" text)
string(FIND "${text}" "${begin_marker}" a)
string(FIND "${text}" "${end_marker}" b)
if(a LESS 0 OR b LESS a)
  message(FATAL_ERROR "${doc}: markers of the generated file list not found")
endif()
string(LENGTH "${end_marker}" n_end)
math(EXPR b_end "${b} + ${n_end}")
math(EXPR len "${b_end} - ${a}")
string(SUBSTRING "${text}" ${a} ${len} current)

if(MODE STREQUAL "update")
  if(NOT current STREQUAL block)
    string(SUBSTRING "${text}" 0 ${a} head)
    string(SUBSTRING "${text}" ${b_end} -1 tail)
    file(WRITE "${doc}" "${head}${block}${tail}")
    message(STATUS "updated the file list of ${doc}")
  endif()
  return()
endif()

if(NOT current STREQUAL block)
  message(FATAL_ERROR "docs/porting.md: the file list differs from the CMake source lists; "
                      "cmake --build build/host --target porting-doc rewrites it. Expected:\n${block}")
endif()

# Build the documented copy, as documented, for each scalar type.
foreach(v CC OUT)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "PortingDoc.cmake: -D${v}=... missing")
  endif()
endforeach()
set(main_c "${OUT}/main.c.in")
file(REMOVE_RECURSE "${OUT}")
file(MAKE_DIRECTORY "${OUT}")
file(WRITE "${main_c}" "#include <stdio.h>
#include \"att.h\"
/* Level, at rest, 100 Hz: aligned after align_samples, then EKF_OK on every sample. */
int main(void)
{
    static att_ekf_t ekf;
    att_sample_t s = {0};
    ekf_scalar_t euler[3];
    int i;
    if (att_init(&ekf, &att_default_settings) != EKF_OK) {
        return 1;
    }
    s.dt = EKF_C(0.01);
    s.accel[2] = EKF_C(9.81);
    s.valid = (uint8_t)(ATT_HAS_GYRO | ATT_HAS_ACCEL);
    for (i = 0; i < 100; ++i) {
        if (att_step(&ekf, &s, NULL) != EKF_OK) {
            return 2;
        }
    }
    att_get_euler(&ekf, euler);
    printf(\"%s: aligned %d, roll %g rad\\n\", EKF_SCALAR_NAME, (att_flags(&ekf) & ATT_FLAG_ALIGNED) != 0,
           ekf_to_double(euler[0]));
    return (att_flags(&ekf) & ATT_FLAG_ALIGNED) ? 0 : 3;
}
")
foreach(scalar FLOAT DOUBLE FIXED)
  file(REMOVE_RECURSE "${OUT}/attekf")
  file(MAKE_DIRECTORY "${OUT}/attekf")
  if(scalar STREQUAL "FIXED")
    file(COPY ${CORE_SOURCES} ${FIXED_SOURCES} ${core_headers} DESTINATION "${OUT}/attekf")
  else()
    file(COPY ${CORE_SOURCES} ${IEEE_SOURCES} ${core_headers} DESTINATION "${OUT}/attekf")
  endif()
  configure_file("${main_c}" "${OUT}/main.c" COPYONLY)
  string(REPLACE "EKF_SCALAR_FLOAT" "EKF_SCALAR_${scalar}" cmd "${cmd_float}")
  string(REGEX REPLACE "^cc " "" cmd "${cmd}")
  separate_arguments(args UNIX_COMMAND "${cmd}")
  file(GLOB sources RELATIVE "${OUT}" "${OUT}/attekf/*.c")
  list(FIND args "attekf/*.c" at)
  list(REMOVE_AT args ${at})
  list(INSERT args ${at} ${sources})
  # the documented line (the shell expands attekf/*.c), plus the project's warnings as errors
  execute_process(COMMAND "${CC}" ${WARNINGS} ${args} WORKING_DIRECTORY "${OUT}"
                  RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e)
  if(NOT rc EQUAL 0 OR NOT e STREQUAL "")
    message(FATAL_ERROR "the documented build (${scalar}) failed or warned: cc ${args}\n${o}${e}")
  endif()
  execute_process(COMMAND "${OUT}/app" RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "the documented build (${scalar}) runs but fails (${rc}): ${o}${e}")
  endif()
  string(STRIP "${o}" o)
  message(STATUS "built as documented: ${o}")
endforeach()
