# The scalar-type guard (ctest: scalar_mismatch_guard): code compiled for one scalar type
# must not build against another type's library, and the error must say so.
#   cmake -DCC=<C compiler> -DINCLUDES="<dir;dir>" -DLIB_D=<libattekf_d.a> -DLIB_F=<libattekf_f.a>
#         -DOUT=<dir> -P mismatch.cmake
# 1. link: a program compiled for float (EKF_SCALAR_FLOAT) linked against the double library
#    fails with "undefined reference to att_init_for_EKF_SCALAR_FLOAT" (ekf_config.h,
#    EKF_SCALAR_LINK_NAME); the same program links against the float library (control);
# 2. compile: two scalar types on one compile line (what a target linking attekf::attekf_f and
#    attekf::attekf_d gets) stop at ekf_config.h's #error.
cmake_minimum_required(VERSION 3.21)
foreach(v CC INCLUDES LIB_D LIB_F OUT)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "mismatch.cmake: -D${v}=... missing")
  endif()
endforeach()
file(MAKE_DIRECTORY "${OUT}")
set(src "${OUT}/mismatch.c")
file(WRITE "${src}" "#include \"att.h\"\nstatic att_ekf_t ekf;\nint main(void) { return att_init(&ekf, &att_default_settings) == EKF_OK ? 0 : 1; }\n")
set(inc "")
foreach(d IN LISTS INCLUDES)
  list(APPEND inc "-I${d}")
endforeach()

execute_process(COMMAND "${CC}" -std=c99 ${inc} -DEKF_SCALAR_FLOAT=1 "${src}" "${LIB_F}" -lm -o "${OUT}/float_float"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "control: float code against the float library does not build:\n${out}${err}")
endif()
execute_process(COMMAND "${OUT}/float_float" RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "control: float code against the float library: att_init failed")
endif()

execute_process(COMMAND "${CC}" -std=c99 ${inc} -DEKF_SCALAR_FLOAT=1 "${src}" "${LIB_D}" -lm -o "${OUT}/float_double"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc EQUAL 0)
  message(FATAL_ERROR "float code linked against the double library: the scalar guard did not stop it")
endif()
if(NOT "${out}${err}" MATCHES "undefined[^\n]*att_init_for_EKF_SCALAR_FLOAT")
  message(FATAL_ERROR "float code against the double library failed, but not with the guard's message:\n${out}${err}")
endif()
string(REGEX MATCH "[^\n]*att_init_for_EKF_SCALAR_FLOAT[^\n]*" line "${err}")
message(STATUS "float code + double library: ${line}")

execute_process(COMMAND "${CC}" -std=c99 ${inc} -DEKF_SCALAR_FLOAT=1 -DEKF_SCALAR_DOUBLE=1 -c "${src}" -o "${OUT}/both.o"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc EQUAL 0 OR NOT err MATCHES "define at most one of EKF_SCALAR_FLOAT, EKF_SCALAR_DOUBLE, EKF_SCALAR_FIXED")
  message(FATAL_ERROR "two scalar types on one compile line were not refused by ekf_config.h:\n${out}${err}")
endif()
string(REGEX MATCH "[^\n]*define at most one[^\n]*" line "${err}")
message(STATUS "two scalar types: ${line}")
