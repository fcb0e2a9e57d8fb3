# ctest entries of the consumer tests (included by tests/CMakeLists.txt, host builds):
#   package_consumer        run.cmake: installed package (find_package), add_subdirectory,
#                           FetchContent, firmware/ alone, pkg-config; C and C++
#   scalar_mismatch_guard   mismatch.cmake: float code does not build against the double library
#   porting_doc_current     cmake/PortingDoc.cmake: docs/porting.md's file list is the CMake
#                           source lists, and the documented copy builds as documented
# Sanitizer builds skip them: a consumer of instrumented libraries would need the same flags,
# and what these tests check does not depend on them.
if(CMAKE_C_FLAGS MATCHES "-fsanitize")
  message(STATUS "tests/consumer: not registered in a sanitizer build")
  return()
endif()
find_program(ATTEKF_PKG_CONFIG NAMES pkg-config pkgconf)
if(NOT ATTEKF_PKG_CONFIG OR NOT CMAKE_GENERATOR STREQUAL "Ninja")
  message(WARNING "tests/consumer: needs pkg-config and the Ninja generator; package_consumer not registered")
else()
  find_program(ATTEKF_CXX NAMES c++ g++ clang++)
  add_test(NAME package_consumer
           COMMAND ${CMAKE_COMMAND} -DSOURCE=${attekf_SOURCE_DIR} -DBUILD=${attekf_BINARY_DIR}
                   -DOUT=${CMAKE_CURRENT_BINARY_DIR}/consumer -DCC=${CMAKE_C_COMPILER}
                   -DCXX=${ATTEKF_CXX} -DPKG_CONFIG=${ATTEKF_PKG_CONFIG}
                   -P ${CMAKE_CURRENT_LIST_DIR}/run.cmake)
  set_tests_properties(package_consumer PROPERTIES LABELS "package" TIMEOUT 300)
endif()
add_test(NAME scalar_mismatch_guard
         COMMAND ${CMAKE_COMMAND} -DCC=${CMAKE_C_COMPILER} "-DINCLUDES=${ATTEKF_CORE_INCLUDES}"
                 -DLIB_F=$<TARGET_FILE:attekf_f> -DLIB_D=$<TARGET_FILE:attekf_d>
                 -DOUT=${CMAKE_CURRENT_BINARY_DIR}/mismatch -P ${CMAKE_CURRENT_LIST_DIR}/mismatch.cmake)
set_tests_properties(scalar_mismatch_guard PROPERTIES LABELS "package")

# The source lists, for the script (cmake -P cannot read firmware/CMakeLists.txt itself).
set(_lists "${CMAKE_CURRENT_BINARY_DIR}/porting_lists.cmake")
file(CONFIGURE OUTPUT "${_lists}" CONTENT "set(ROOT [[${attekf_SOURCE_DIR}]])
set(CORE_SOURCES [[${ATTEKF_CORE_SOURCES}]])
set(IEEE_SOURCES [[${ATTEKF_IEEE_SOURCES}]])
set(FIXED_SOURCES [[${ATTEKF_FIXED_SOURCES}]])
set(CORE_INCLUDES [[${ATTEKF_CORE_INCLUDES}]])
set(PUBLIC_HEADERS [[${ATTEKF_CORE_HEADERS}]])
set(MODELS_SOURCES [[${ATTEKF_MODELS_SOURCES}]])
set(MODELS_INCLUDES [[${ATTEKF_MODELS_INCLUDES}]])
set(MODELS_HEADERS [[${ATTEKF_MODELS_HEADERS}]])
set(WARNINGS [[${ATTEKF_WARNINGS}]])
")
add_test(NAME porting_doc_current
         COMMAND ${CMAKE_COMMAND} -DLISTS=${_lists} -DMODE=check -DCC=${CMAKE_C_COMPILER}
                 -DOUT=${CMAKE_CURRENT_BINARY_DIR}/porting -P ${attekf_SOURCE_DIR}/cmake/PortingDoc.cmake)
set_tests_properties(porting_doc_current PROPERTIES LABELS "package;docs")
add_custom_target(porting-doc
                  COMMAND ${CMAKE_COMMAND} -DLISTS=${_lists} -DMODE=update
                          -P ${attekf_SOURCE_DIR}/cmake/PortingDoc.cmake
                  COMMENT "docs/porting.md: file list from the CMake source lists" VERBATIM)
