# Cortex-M4 with the single-precision FPU (hard-float ABI), e.g. STM32F4, nRF52.
# Emulated by QEMU's mps2-an386 board.
#   cmake -S . -B build/cortex-m4f -G Ninja --toolchain cmake/toolchains/cortex-m4f.cmake
# or the cortex-m4f preset of CMakePresets.json.
set(ATTEKF_QEMU_MACHINE mps2-an386)
set(ATTEKF_CPU_FLAGS "-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard")
include("${CMAKE_CURRENT_LIST_DIR}/arm-none-eabi.cmake")
