#!/usr/bin/env bash
# Cross builds under QEMU, the Cortex-M part of the test suite (called by scripts/test.sh):
# configures and builds build/cortex-m4f, build/cortex-m3 and build/cortex-m3-fixed (the
# Q-format fixed-point build, docs/fixed_point.md) from CMakePresets.json, then
# runs their ctest, which runs every image through firmware/target/qemu_run.sh:
#   the core's and the application's Unity tests marked ON_TARGET (float build),
#   firmware_bench_runs (benchmark image, SysTick instruction counting works),
#   firmware_equals_host (firmware output vs build/host's attekf-fw-host, 1e-5 rad).
# About 70 s on 2 cores (docs/performance.md, "Cortex-M test-suite stage").
# Needs build/host built first (scripts/setup.sh does it). Exit status non-zero on failure;
# without the cross compiler or QEMU: fails under CI=true, else skipped (exit 77, prereq.sh).
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
# shellcheck source=scripts/prereq.sh
. "$ROOT/scripts/prereq.sh"
attekf_require target arm-none-eabi-gcc arm-none-eabi-nm qemu-system-arm
JOBS="$(nproc)"
status=0
for preset in cortex-m4f cortex-m3 cortex-m3-fixed; do
  start=$SECONDS
  echo "[test] $preset: configure + build (build/$preset)"
  if ! cmake --preset "$preset" >/dev/null; then
    echo "[test] $preset: configure failed" >&2
    status=1
    continue
  fi
  if ! cmake --build --preset "$preset" -j"$JOBS" >/dev/null; then
    cmake --build --preset "$preset" -j1 2>&1 | tail -40 # show the error
    echo "[test] $preset: build failed" >&2
    status=1
    continue
  fi
  echo "[test] $preset: ctest under QEMU"
  ctest --preset "$preset" -j"$JOBS" --no-tests=error || status=1
  echo "[test] $preset: $((SECONDS - start)) s"
done
exit "$status"
