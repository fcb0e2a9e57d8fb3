# Cortex-M3 (no FPU: every float operation is a libgcc soft-float call), e.g. STM32F1.
# Emulated by QEMU's mps2-an385 board.
#   cmake -S . -B build/cortex-m3 -G Ninja --toolchain cmake/toolchains/cortex-m3.cmake
# or the cortex-m3 preset of CMakePresets.json.
set(ATTEKF_QEMU_MACHINE mps2-an385)
set(ATTEKF_CPU_FLAGS "-mcpu=cortex-m3 -mthumb -mfloat-abi=soft")
include("${CMAKE_CURRENT_LIST_DIR}/arm-none-eabi.cmake")
