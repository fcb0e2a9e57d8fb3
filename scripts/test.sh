#!/usr/bin/env bash
# Runs the whole test suite: installs/builds what is missing (scripts/setup.sh --no-demo),
# then the C tests (Unity, driven by ctest) and the Python tests (pytest).
# Exit status is non-zero if any test fails. Used by .ci/run.
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
JOBS="$(nproc)"

"$ROOT/scripts/setup.sh" --no-demo || { echo "[test] set-up failed" >&2; exit 1; }

status=0
echo "[test] ctest (build/host)"
ctest --test-dir "$ROOT/build/host" --output-on-failure -j"$JOBS" || status=1

echo "[test] Cortex-M builds under QEMU (scripts/test_target.sh)"
"$ROOT/scripts/test_target.sh" || status=1

echo "[test] pytest"
"$ROOT/.venv/bin/python" -m pytest "$ROOT/tests/python" -q -ra || status=1

# The pip package as a user gets it: sdist -> wheel (CMake) -> a fresh virtual environment
# outside the repository, every command and the Python API there (tests/package/).
echo "[test] Python package from its sdist in a fresh virtual environment (tests/package)"
"$ROOT/.venv/bin/python" -m pytest "$ROOT/tests/package" -q -ra || status=1

# Reliability (docs/reliability.md): static analysis, the ctest under ASan + UBSan, valgrind on
# the node, a short fuzz run of every target (scripts/fuzz.sh --time 3600 for a long one).
echo "[test] static analysis: cppcheck + clang-tidy (scripts/static_analysis.sh)"
"$ROOT/scripts/static_analysis.sh" || status=1
echo "[test] ctest under ASan + UBSan (scripts/test_sanitizers.sh)"
"$ROOT/scripts/test_sanitizers.sh" || status=1
echo "[test] valgrind memcheck on attekf-node (scripts/test_valgrind.sh)"
"$ROOT/scripts/test_valgrind.sh" || status=1
echo "[test] fuzzing, 60 s per target, mutation seed 1 (scripts/fuzz.sh)"
"$ROOT/scripts/fuzz.sh" --time 60 --seed 1 || status=1

if [ "$status" -ne 0 ]; then
  echo "[test] FAILED"
else
  echo "[test] all passed"
fi
exit "$status"
