# The installed package, add_subdirectory, FetchContent and pkg-config, as a user meets them
# (ctest: package_consumer; tests/CMakeLists.txt passes the variables):
#   cmake -DSOURCE=<attekf source> -DBUILD=<attekf build to install> -DOUT=<work dir>
#         -DCC=<C compiler> -DCXX=<C++ compiler> -DPKG_CONFIG=<pkg-config> -P run.cmake
#
# 1. cmake --install BUILD --prefix OUT/prefix;
# 2. tests/consumer (this directory) configured and built against it four ways: package
#    (find_package), subdir (add_subdirectory), fetch (FetchContent), firmware
#    (add_subdirectory of firmware/ alone); each runs readme_c, readme_cxx (the README's C
#    snippet as C and as C++) and headers_cxx (every public header as C++, the model library);
# 3. the pkg-config files: their compile and link lines, and the README program built with
#    nothing but them;
# 4. every installed header carries the extern "C" guard.
# All README programs must print the same line. Work directories are kept between runs, so
# a second run rebuilds only what changed.
cmake_minimum_required(VERSION 3.21)
foreach(v SOURCE BUILD OUT CC CXX PKG_CONFIG)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "run.cmake: -D${v}=... missing")
  endif()
endforeach()
set(prefix "${OUT}/prefix")
set(here "${CMAKE_CURRENT_LIST_DIR}")

function(run what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${what} failed (${rc}):\n${out}${err}")
  endif()
  set(out "${out}" PARENT_SCOPE)
endfunction()

file(REMOVE_RECURSE "${prefix}")
run("cmake --install" "${CMAKE_COMMAND}" --install "${BUILD}" --prefix "${prefix}")

# 4. extern "C" guards, exactly the project's pattern
file(GLOB headers "${prefix}/include/attekf/*.h")
foreach(h IN LISTS headers)
  file(READ "${h}" text)
  string(FIND "${text}" "#ifdef __cplusplus\nextern \"C\" {\n#endif\n" open)
  string(FIND "${text}" "#ifdef __cplusplus\n}\n#endif\n" close)
  if(open LESS 0 OR close LESS open)
    message(FATAL_ERROR "${h}: no extern \"C\" guard (docs/porting.md)")
  endif()
endforeach()

set(lines "")
foreach(mode package subdir fetch firmware)
  set(bin "${OUT}/${mode}")
  run("configure (${mode})" "${CMAKE_COMMAND}" -S "${here}" -B "${bin}" -G Ninja
      -DCMAKE_C_COMPILER=${CC} -DCMAKE_CXX_COMPILER=${CXX} -DCMAKE_BUILD_TYPE=Release
      -DATTEKF_CONSUME=${mode} -DATTEKF_SOURCE=${SOURCE} -DCMAKE_PREFIX_PATH=${prefix})
  run("build (${mode})" "${CMAKE_COMMAND}" --build "${bin}" --target readme_c readme_cxx headers_cxx)
  run("headers_cxx (${mode})" "${bin}/headers_cxx")
  foreach(exe readme_c readme_cxx)
    run("${exe} (${mode})" "${bin}/${exe}")
    message(STATUS "${mode} ${exe}: ${out}")
    list(APPEND lines "${out}")
  endforeach()
endforeach()

# 3. pkg-config
set(ENV{PKG_CONFIG_PATH} "${prefix}/lib/pkgconfig")
set(ENV{PKG_CONFIG_LIBDIR} "${prefix}/lib/pkgconfig")
run("pkg-config attekf_f" "${PKG_CONFIG}" --cflags --libs attekf_f)
string(STRIP "${out}" pc)
message(STATUS "pkg-config --cflags --libs attekf_f: ${pc}")
separate_arguments(pc_args UNIX_COMMAND "${pc}")
if(NOT "-DEKF_SCALAR_FLOAT=1" IN_LIST pc_args OR NOT "-lattekf_f" IN_LIST pc_args OR NOT "-lm" IN_LIST pc_args)
  message(FATAL_ERROR "pkg-config attekf_f: unexpected line '${pc}'")
endif()
list(FILTER pc_args INCLUDE REGEX "^-I")
list(LENGTH pc_args n_inc)
list(GET pc_args 0 inc)
string(SUBSTRING "${inc}" 2 -1 inc)
if(NOT n_inc EQUAL 1 OR NOT EXISTS "${inc}/att.h")
  message(FATAL_ERROR "pkg-config attekf_f: one include directory with att.h expected, got '${pc}'")
endif()
run("pkg-config attekf_models_d" "${PKG_CONFIG}" --cflags --libs attekf_models_d)
string(STRIP "${out}" pc_models)
if(NOT pc_models MATCHES "-DEKF_SCALAR_DOUBLE=1" OR NOT pc_models MATCHES "-lattekf_models_d -lattekf_d")
  message(FATAL_ERROR "pkg-config attekf_models_d: unexpected line '${pc_models}'")
endif()
separate_arguments(pc_args UNIX_COMMAND "${pc}")
run("cc with pkg-config's flags" "${CC}" -std=c99 -Wall -Wextra -Werror -I${OUT}/package/readme
    "${here}/readme_main.c" ${pc_args} -o "${OUT}/readme_pkgconfig")
run("readme_pkgconfig" "${OUT}/readme_pkgconfig")
message(STATUS "pkg-config build: ${out}")
list(APPEND lines "${out}")

list(GET lines 0 first)
foreach(line IN LISTS lines)
  if(NOT line STREQUAL first)
    message(FATAL_ERROR "the README programs disagree:\n${lines}")
  endif()
endforeach()
message(STATUS "consumer: package, add_subdirectory, FetchContent, firmware/ alone and pkg-config "
               "builds agree, C and C++: ${first}")
