#!/usr/bin/env bash
# Runs the whole test suite: installs/builds what is missing (scripts/setup.sh --no-demo),
# then the C tests (Unity, driven by ctest), the Cortex-M tests under QEMU, the Python tests
# (pytest) and the reliability stages. Exit status is non-zero if any test fails. Used by
# .ci/run, which exports CI=true: then a missing tool or the missing BROAD data
# (../shared/data/broad) fails the run; elsewhere the tests and stages that need them skip
# and say why (scripts/prereq.sh, tests/python/prereq.py, tests/RunTest.cmake).
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
JOBS="$(nproc)"

# Each stage's wall time, printed at the end: the whole suite must stay under 12 minutes on
# 2 cores, and these say where the time goes.
times=()
t_setup=$SECONDS
"$ROOT/scripts/setup.sh" --no-demo || { echo "[test] set-up failed" >&2; exit 1; }
times+=("$((SECONDS - t_setup)) s  set-up (scripts/setup.sh --no-demo)")

# shellcheck source=scripts/prereq.sh
. "$ROOT/scripts/prereq.sh"
status=0
failed=()
skipped=()
# record <title> <exit status> <start, s>: a stage's time and result; exit 77 means "skipped,
# tool missing" (prereq.sh), which under CI=true counts as a failure like any other status.
record() {
  times+=("$((SECONDS - $3)) s  $1")
  if [ "$2" -eq 0 ]; then
    return
  elif [ "$2" -eq 77 ] && ! attekf_in_ci; then
    skipped+=("$1")
  else
    failed+=("$1 (exit $2)")
    status=1
  fi
}
# step <title> <command...>: runs one stage.
step() {
  local title="$1" t0=$SECONDS
  shift
  echo "[test] $title"
  "$@"
  record "$title" $? "$t0"
}
# beside <title> <command...>: starts a stage that runs beside the next ones, its output to a
# log shown by beside_wait when it ends. For a stage that leaves a core idle beside one that
# keeps only one busy; the two share no files they write.
beside() {
  beside_title="$1" beside_t0=$SECONDS beside_log="$ROOT/build/test-beside.log"
  shift
  echo "[test] $beside_title (beside the next stage; its output follows when it ends)"
  "$@" > "$beside_log" 2>&1 &
  beside_pid=$!
}
beside_wait() {
  wait "$beside_pid"
  local rc=$?
  echo "[test] $beside_title:"
  cat "$beside_log"
  record "$beside_title" "$rc" "$beside_t0"
}

step "ctest (build/host)" ctest --test-dir "$ROOT/build/host" --output-on-failure --no-tests=error -j"$JOBS"
# ctest lists skipped tests without their reason; tests/RunTest.cmake logged it
grep -h "^ATTEKF-SKIP:" "$ROOT/build/host/Testing/Temporary/LastTest.log" 2>/dev/null | sed 's/^/[test] ctest /'
step "Cortex-M builds under QEMU (scripts/test_target.sh)" "$ROOT/scripts/test_target.sh"
# The pip package as a user gets it: sdist -> wheel (CMake) -> a fresh virtual environment
# outside the repository, every command and the Python API there (tests/package/). Mostly
# downloads and one compile, so it runs beside pytest, which keeps one core busy (one process;
# the HIL's guests have one virtual CPU); its compile is held to one job for the same reason.
CMAKE_BUILD_PARALLEL_LEVEL=1 beside "Python package from its sdist in a fresh virtual environment (tests/package)" \
  "$ROOT/.venv/bin/python" -m pytest "$ROOT/tests/package" -q -ra -p no:cacheprovider
step "pytest" "$ROOT/.venv/bin/python" -m pytest "$ROOT/tests/python" -q -ra --durations=15
beside_wait

# Reliability (docs/reliability.md): static analysis, the ctest under ASan + UBSan, valgrind on
# the node, a short fuzz run of every target (scripts/fuzz.sh --time 3600 for a long one).
step "static analysis: cppcheck + clang-tidy (scripts/static_analysis.sh)" "$ROOT/scripts/static_analysis.sh"
step "ctest under ASan + UBSan (scripts/test_sanitizers.sh)" "$ROOT/scripts/test_sanitizers.sh"
step "valgrind memcheck on attekf-node (scripts/test_valgrind.sh)" "$ROOT/scripts/test_valgrind.sh"
step "fuzzing, 60 s per target, mutation seed 1 (scripts/fuzz.sh)" "$ROOT/scripts/fuzz.sh" --time 60 --seed 1

echo "[test] wall time per stage (total $SECONDS s):"
for t in "${times[@]}"; do echo "[test]   $t"; done
for s in "${skipped[@]}"; do echo "[test] SKIPPED (a tool is missing, see above): $s"; done
for s in "${failed[@]}"; do echo "[test] FAILED: $s"; done
if [ "$status" -ne 0 ]; then
  echo "[test] FAILED"
elif ((${#skipped[@]})); then
  echo "[test] passed, ${#skipped[@]} stage(s) skipped"
else
  echo "[test] all passed"
fi
exit "$status"
