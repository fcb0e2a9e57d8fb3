#!/usr/bin/env bash
# Runs a cross-built firmware image on an emulated Cortex-M board with semihosting.
#
#   qemu_run.sh [--machine mps2-an386] [--icount SHIFT] [--trace LOG] <image.elf> [args...]
#
# The image's argv is passed through semihosting (SYS_GET_CMDLINE), its console and file
# I/O go to this process (paths relative to the current directory), and its exit(n) becomes
# this script's exit status (QEMU's own failures: 1; a CPU lockup: QEMU aborts, 134).
#   --machine   QEMU board: mps2-an386 (Cortex-M4F, default), mps2-an385 (Cortex-M3)
#   --icount N  deterministic virtual time, 2^N ns per instruction (SysTick then counts
#               instructions: 6.4 ticks per instruction at N = 8 on the 25 MHz mps2 clock)
#   --trace F   one line per executed instruction, with its symbol, into F (slow; profiling)
# CMake uses it as CMAKE_CROSSCOMPILING_EMULATOR (cmake/toolchains/arm-none-eabi.cmake).
set -euo pipefail

machine=mps2-an386
icount=()
trace=()
while (($#)); do
  case "$1" in
    --machine) machine="$2"; shift 2 ;;
    --icount) icount=(-icount "shift=$2"); shift 2 ;;
    --trace) trace=(-singlestep -d exec,nochain -D "$2"); shift 2 ;;
    -h|--help) sed -n '2,15p' "$0"; exit 0 ;;
    --) shift; break ;;
    -*) echo "qemu_run.sh: unknown option '$1' (see --help)" >&2; exit 2 ;;
    *) break ;;
  esac
done
if (($# < 1)); then
  echo "qemu_run.sh: no image given (see --help)" >&2
  exit 2
fi
image="$1"
if [ ! -f "$image" ]; then
  echo "qemu_run.sh: no such image: $image" >&2
  exit 2
fi

# QEMU's option syntax: ',' separates keys, a literal ',' is written ',,'.
semi="enable=on,target=native"
for a in "$@"; do
  semi+=",arg=${a//,/,,}"
done

# No display, no UART, no monitor: semihosting is the only console, and QEMU never
# touches the terminal (tests run in parallel and without stdin in CI).
exec qemu-system-arm -M "$machine" -display none -serial null -monitor none \
  "${icount[@]}" "${trace[@]}" -semihosting-config "$semi" -kernel "$image" </dev/null
