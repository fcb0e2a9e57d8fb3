#!/usr/bin/env bash
# The ctest under AddressSanitizer + UndefinedBehaviorSanitizer (configure preset host-asan:
# every finding fatal, leaks included), docs/reliability.md. Every test that runs project C
# code runs; left out are the labels codegen (Python generators vs committed files) and
# cross (arm-none-eabi compile checks), which run no instrumented code and are in the
# plain ctest anyway.
#
#   ./scripts/test_sanitizers.sh [BUILD_DIR]    default build/host-asan
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
OUT="${1:-$ROOT/build/host-asan}"
JOBS="$(nproc)"
t0=$SECONDS
cmake --preset host-asan -B "$OUT" >/dev/null || { echo "[asan] configure failed" >&2; exit 1; }
cmake --build "$OUT" -j"$JOBS" >/dev/null || { cmake --build "$OUT" 2>&1 | grep -E "error|FAILED" | head -20 >&2; echo "[asan] build failed" >&2; exit 1; }
echo "[asan] built in $((SECONDS - t0)) s"
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:strict_string_checks=1:detect_stack_use_after_return=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
t0=$SECONDS
ctest --test-dir "$OUT" --output-on-failure --no-tests=error -j"$JOBS" -LE "codegen|cross"
rc=$?
echo "[asan] ctest in $((SECONDS - t0)) s: $([ $rc -eq 0 ] && echo 'no sanitizer findings, all passed' || echo FAILED)"
exit $rc
