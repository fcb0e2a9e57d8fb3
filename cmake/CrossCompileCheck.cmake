# cmake -DCC=<arm-none-eabi-gcc> -DNM=<arm-none-eabi-nm> -DSRC_DIR=<repo> -DOUT=<dir>
#       -DSOURCES="a.c;b.c" -DINCLUDES="dir;dir" -P CrossCompileCheck.cmake
#
# Compiles the estimator library for Cortex-M4F (hard float) with the project's warnings
# as errors, then checks the objects for hidden double precision: a float build must not
# reference the soft-double helpers (__aeabi_d*) or double libm functions (sin, cos, ...).
include("${CMAKE_CURRENT_LIST_DIR}/Warnings.cmake")
if(NOT SOURCES)
  message(FATAL_ERROR "cortex-m4f: no source files given (-DSOURCES): nothing would be checked")
endif()
set(flags -std=c99 -Os -mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard
          -ffunction-sections -fdata-sections -DEKF_SCALAR_FLOAT=1 ${ATTEKF_WARNINGS})
foreach(inc ${INCLUDES})
  list(APPEND flags "-I${inc}")
endforeach()
file(MAKE_DIRECTORY "${OUT}")
set(objects "")
foreach(src ${SOURCES})
  get_filename_component(name "${src}" NAME_WE)
  set(obj "${OUT}/${name}.o")
  execute_process(COMMAND "${CC}" ${flags} -c "${src}" -o "${obj}"
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "cortex-m4f compile failed: ${src}\n${out}${err}")
  endif()
  if(err)
    message(FATAL_ERROR "cortex-m4f compile printed diagnostics: ${src}\n${err}")
  endif()
  list(APPEND objects "${obj}")
endforeach()
execute_process(COMMAND "${NM}" -u ${objects} OUTPUT_VARIABLE undefined RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "nm failed")
endif()
string(REGEX MATCHALL "[ \t]U (__aeabi_d[a-z0-9_]*|sin|cos|tan|atan2|sqrt|floor|fabs|asin|acos|atan)\n" bad "${undefined}")
if(bad)
  message(FATAL_ERROR "double precision in the float build:\n${bad}")
endif()
message(STATUS "cortex-m4f: ${SOURCES} compiled warning-free, no double precision referenced")
