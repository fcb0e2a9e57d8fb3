# Install and export rules (ATTEKF_INSTALL), included by the root CMakeLists.txt.
#
#   <prefix>/include/attekf/                 the public headers of the core and the models
#   <prefix>/lib/libattekf_{f,d,x}.a         estimator library per scalar type
#   <prefix>/lib/libattekf_models_{f,d}.a    model library per scalar type
#   <prefix>/lib/cmake/attekf/               find_package(attekf CONFIG): imported targets
#                                            attekf::attekf_f, _d, _x, attekf::attekf_models_f, _d
#   <prefix>/lib/pkgconfig/attekf_*.pc       one pkg-config file per library
#
# The build tree is a package too: find_package(attekf) with attekf_DIR=<build dir>.
include(CMakePackageConfigHelpers)

set(_libs attekf_f attekf_d attekf_x attekf_models_f attekf_models_d)
set(_cmakedir "${CMAKE_INSTALL_LIBDIR}/cmake/attekf")

install(TARGETS ${_libs} EXPORT attekfTargets
        ARCHIVE DESTINATION "${CMAKE_INSTALL_LIBDIR}")
install(FILES ${ATTEKF_CORE_HEADERS} ${ATTEKF_MODELS_HEADERS}
        DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}/attekf")
install(EXPORT attekfTargets NAMESPACE attekf:: DESTINATION "${_cmakedir}")
export(EXPORT attekfTargets NAMESPACE attekf:: FILE "${PROJECT_BINARY_DIR}/attekfTargets.cmake")

# 0.x: a minor version may change the API, so only the same minor version is compatible.
write_basic_package_version_file("${PROJECT_BINARY_DIR}/attekfConfigVersion.cmake"
                                 COMPATIBILITY SameMinorVersion)
configure_package_config_file("${CMAKE_CURRENT_LIST_DIR}/attekfConfig.cmake.in"
                              "${PROJECT_BINARY_DIR}/cmake-install/attekfConfig.cmake"
                              INSTALL_DESTINATION "${_cmakedir}")
configure_package_config_file("${CMAKE_CURRENT_LIST_DIR}/attekfConfig.cmake.in"
                              "${PROJECT_BINARY_DIR}/attekfConfig.cmake"
                              INSTALL_DESTINATION "${PROJECT_BINARY_DIR}"
                              INSTALL_PREFIX "${PROJECT_BINARY_DIR}")
install(FILES "${PROJECT_BINARY_DIR}/cmake-install/attekfConfig.cmake"
              "${PROJECT_BINARY_DIR}/attekfConfigVersion.cmake"
        DESTINATION "${_cmakedir}")

# pkg-config: the prefix is found relative to the .pc file, so a tree installed with
# cmake --install --prefix <anywhere> (or moved) stays right.
set(_pcdir "${CMAKE_INSTALL_LIBDIR}/pkgconfig")
if(IS_ABSOLUTE "${CMAKE_INSTALL_LIBDIR}")
  set(ATTEKF_PC_PREFIX "${CMAKE_INSTALL_PREFIX}")
else()
  file(RELATIVE_PATH _up "/root/${_pcdir}" "/root")
  string(REGEX REPLACE "/$" "" _up "${_up}")
  set(ATTEKF_PC_PREFIX "\${pcfiledir}/${_up}")
endif()
if(CMAKE_CROSSCOMPILING)
  set(ATTEKF_PC_LIBM "")
else()
  set(ATTEKF_PC_LIBM " -lm")
endif()
set(_scalar_f FLOAT)
set(_scalar_d DOUBLE)
set(_scalar_x FIXED)
set(_what_f "float")
set(_what_d "double")
set(_what_x "Q-format fixed-point")
foreach(_suffix f d x)
  set(ATTEKF_PC_NAME "attekf_${_suffix}")
  set(ATTEKF_PC_DESCRIPTION "attitude EKF, ${_what_${_suffix}} build")
  set(ATTEKF_PC_REQUIRES "")
  set(ATTEKF_PC_CFLAGS " -DEKF_SCALAR_${_scalar_${_suffix}}=1")
  set(ATTEKF_PC_LIBS "-lattekf_${_suffix}${ATTEKF_PC_LIBM}")
  configure_file("${CMAKE_CURRENT_LIST_DIR}/attekf.pc.in" "${PROJECT_BINARY_DIR}/pkgconfig/attekf_${_suffix}.pc" @ONLY)
  if(TARGET attekf_models_${_suffix})
    set(ATTEKF_PC_NAME "attekf_models_${_suffix}")
    set(ATTEKF_PC_DESCRIPTION "EKF model library (constant acceleration, radar, SLAM), ${_what_${_suffix}} build")
    set(ATTEKF_PC_REQUIRES "attekf_${_suffix}")
    set(ATTEKF_PC_CFLAGS "")
    set(ATTEKF_PC_LIBS "-lattekf_models_${_suffix}")
    configure_file("${CMAKE_CURRENT_LIST_DIR}/attekf.pc.in" "${PROJECT_BINARY_DIR}/pkgconfig/attekf_models_${_suffix}.pc" @ONLY)
  endif()
endforeach()
install(DIRECTORY "${PROJECT_BINARY_DIR}/pkgconfig/" DESTINATION "${_pcdir}")
