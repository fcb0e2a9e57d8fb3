# Unity 2.6.1 (ThrowTheSwitch, MIT) for the C tests.
#
# Unity is not packaged by Debian. By default it is taken from the PyPI wheel
# vyperling==0.0.4, which carries Unity 2.6.1's sources byte-identical to upstream under
# vyperling/c/. The wheel is downloaded with pip at configure time (pinned version),
# its SHA-256 and the SHA-256 of each extracted file are checked, and the files are
# extracted into the build tree. Nothing of Unity is committed.
#
# A user with Unity elsewhere sets -DUNITY_DIR=/path/containing/unity.c (the hashes are
# then not checked: it is the user's copy).

set(UNITY_DIR "" CACHE PATH "Directory with Unity's unity.c/unity.h/unity_internals.h (empty: fetch the pinned wheel)")

set(_unity_wheel_name "vyperling-0.0.4-py3-none-any.whl")
set(_unity_wheel_sha256 "028f4419cf4f49cfaed51256290718753a78cc035923fbf43acc8bcd62d205cb")
set(_unity_file_sha256_unity.c "b90e735a54cf3b3765ab6caa955d11a1488ee73d9c6152cdc98576c2d17cb871")
set(_unity_file_sha256_unity.h "9db174d3c2c6424fd35c0980c5941d124c5ebb0f48e8172f997a2aa9554b64ea")
set(_unity_file_sha256_unity_internals.h "fcd8b3f6b412ac0ab599547eb8a30b6d7f3f0af77aab31f7a1822a2a8fc9a2b2")

if(UNITY_DIR)
  set(_unity_src "${UNITY_DIR}")
  foreach(f unity.c unity.h unity_internals.h)
    if(NOT EXISTS "${_unity_src}/${f}")
      message(FATAL_ERROR "UNITY_DIR=${UNITY_DIR} has no ${f}")
    endif()
  endforeach()
else()
  set(_unity_dl "${attekf_BINARY_DIR}/_deps/unity-download")
  set(_unity_src "${attekf_BINARY_DIR}/_deps/unity-2.6.1")
  # A wheel already fetched by another build tree is reused (still hash-checked).
  set(_unity_cache "$ENV{HOME}/.cache/attekf")
  set(_wheel "${_unity_dl}/${_unity_wheel_name}")
  if(NOT EXISTS "${_wheel}" AND EXISTS "${_unity_cache}/${_unity_wheel_name}")
    file(COPY "${_unity_cache}/${_unity_wheel_name}" DESTINATION "${_unity_dl}")
  endif()
  if(NOT EXISTS "${_wheel}")
    find_package(Python3 COMPONENTS Interpreter REQUIRED)
    message(STATUS "Unity: downloading vyperling==0.0.4 from PyPI")
    execute_process(
      COMMAND "${Python3_EXECUTABLE}" -m pip download --quiet --disable-pip-version-check
              --no-deps --only-binary=:all: -d "${_unity_dl}" vyperling==0.0.4
      RESULT_VARIABLE _rc)
    if(NOT _rc EQUAL 0 OR NOT EXISTS "${_wheel}")
      message(FATAL_ERROR "Unity: could not download vyperling==0.0.4 (pip exit ${_rc}). "
                          "Set -DUNITY_DIR to a Unity 2.6 source directory instead.")
    endif()
  endif()
  file(SHA256 "${_wheel}" _got)
  if(NOT _got STREQUAL _unity_wheel_sha256)
    file(REMOVE "${_wheel}")
    message(FATAL_ERROR "Unity: wheel SHA-256 mismatch: got ${_got}, want ${_unity_wheel_sha256}")
  endif()
  file(MAKE_DIRECTORY "${_unity_cache}")
  file(COPY "${_wheel}" DESTINATION "${_unity_cache}")
  set(_unity_x "${_unity_dl}/x")
  file(REMOVE_RECURSE "${_unity_x}")
  file(ARCHIVE_EXTRACT INPUT "${_wheel}" DESTINATION "${_unity_x}"
       PATTERNS "vyperling/c/unity.c" "vyperling/c/unity.h" "vyperling/c/unity_internals.h"
                "vyperling/c/UNITY_LICENSE")
  file(MAKE_DIRECTORY "${_unity_src}")
  foreach(f unity.c unity.h unity_internals.h)
    file(SHA256 "${_unity_x}/vyperling/c/${f}" _got)
    if(NOT _got STREQUAL _unity_file_sha256_${f})
      message(FATAL_ERROR "Unity: ${f} SHA-256 mismatch: got ${_got}")
    endif()
    file(COPY "${_unity_x}/vyperling/c/${f}" DESTINATION "${_unity_src}")
  endforeach()
  file(GLOB _unity_lic "${_unity_x}/vyperling/c/UNITY_LICENSE")
  if(_unity_lic)
    file(COPY ${_unity_lic} DESTINATION "${_unity_src}")
  endif()
endif()

# Unity is third-party code: built with its own (still strict) flags, not the project's
# -Wconversion/-Wdouble-promotion set, which it was not written for.
function(attekf_add_unity name)
  add_library(${name} STATIC "${_unity_src}/unity.c")
  target_include_directories(${name} SYSTEM PUBLIC "${_unity_src}")
  target_compile_definitions(${name} PUBLIC ${ARGN})
  target_compile_options(${name} PRIVATE -std=c99 -w)
endfunction()
