# Common part of the bare-metal Arm toolchain files (cortex-m4f.cmake, cortex-m3.cmake).
# Not used directly: a CPU file sets ATTEKF_CPU_FLAGS (compiler CPU/FPU options) and
# ATTEKF_QEMU_MACHINE (the QEMU board that emulates it), then includes this file.
#
# Toolchain: Debian gcc-arm-none-eabi + libnewlib-arm-none-eabi (newlib, semihosting via
# librdimon). Emulator: qemu-system-arm (mps2 boards); the firmware's startup code, linker
# scripts and QEMU runner live in firmware/target/.

set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

find_program(ARM_NONE_EABI_GCC arm-none-eabi-gcc REQUIRED)
get_filename_component(_arm_bin "${ARM_NONE_EABI_GCC}" DIRECTORY)
set(CMAKE_C_COMPILER "${ARM_NONE_EABI_GCC}")
set(CMAKE_ASM_COMPILER "${ARM_NONE_EABI_GCC}")
set(CMAKE_AR "${_arm_bin}/arm-none-eabi-ar" CACHE FILEPATH "archiver")
set(CMAKE_RANLIB "${_arm_bin}/arm-none-eabi-ranlib" CACHE FILEPATH "ranlib")
set(CMAKE_SIZE "${_arm_bin}/arm-none-eabi-size" CACHE FILEPATH "arm-none-eabi-size")
set(CMAKE_OBJDUMP "${_arm_bin}/arm-none-eabi-objdump" CACHE FILEPATH "objdump")

# The compiler checks only compile: linking needs the project's startup code and linker
# script, which do not exist yet when CMake probes the compiler.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

# -ffunction-sections/-fdata-sections + --gc-sections: unused functions do not reach the
# image, so the footprint measured is what the application really uses.
# -fno-math-errno: libm calls need not set errno (nothing in the project reads it; the
# estimator checks results for finiteness itself), so sqrtf becomes the FPU's VSQRT
# instead of a call to newlib's wrapper, which also drags in newlib's 1 KiB reentrancy
# struct for errno. Results are unchanged (VSQRT and sqrtf are both correctly rounded).
set(CMAKE_C_FLAGS_INIT "${ATTEKF_CPU_FLAGS} -ffunction-sections -fdata-sections -fno-math-errno")
set(CMAKE_ASM_FLAGS_INIT "${ATTEKF_CPU_FLAGS}")
set(CMAKE_EXE_LINKER_FLAGS_INIT "${ATTEKF_CPU_FLAGS} -Wl,--gc-sections")
# libm last on every link line (after the libraries that call sinf & co.); newlib's libc
# and the semihosting library come from --specs=rdimon.specs (firmware/target).
set(CMAKE_C_STANDARD_LIBRARIES_INIT "-lm")
# Firmware is not position independent; -fPIC would cost a GOT indirection per global.
set(CMAKE_POSITION_INDEPENDENT_CODE OFF)

set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

# ctest (and anything else that honours CMAKE_CROSSCOMPILING_EMULATOR) runs the
# cross-built executables on the emulated board through the runner, which turns
# "runner <elf> <args...>" into a QEMU command line with semihosting arguments.
set(CMAKE_CROSSCOMPILING_EMULATOR
    "${CMAKE_CURRENT_LIST_DIR}/../../firmware/target/qemu_run.sh;--machine;${ATTEKF_QEMU_MACHINE}")
