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

# Each stage's wall time and CPU time (user + system, its processes), printed at the end: the
# whole suite must stay under 12 minutes on 2 cores, and these say where the time goes (CPU
# time does not depend on what else the machine runs; wall time does).
times=()
mkdir -p "$ROOT/build"
CPU_FILE="$ROOT/build/test-cpu.txt"
cpu_now() {  # CPU: seconds used so far by this shell's finished children
  times > "$CPU_FILE"
  CPU="$(awk 'NR == 2 { s = 0; for (i = 1; i <= NF; i++) { split($i, b, "m"); sub("s", "", b[2]); s += b[1] * 60 + b[2] }
                        printf "%.0f", s }' "$CPU_FILE")"
}
cpu_now
cpu0=$CPU
"$ROOT/scripts/setup.sh" --no-demo || { echo "[test] set-up failed" >&2; exit 1; }
cpu_now
times+=("$SECONDS s wall, $((CPU - cpu0)) s CPU  set-up (scripts/setup.sh --no-demo)")

# shellcheck source=scripts/prereq.sh
. "$ROOT/scripts/prereq.sh"
status=0
failed=()
skipped=()
# record <title> <exit status> <wall s> <CPU s>: a stage's times and result; exit 77 means
# "skipped, tool missing" (prereq.sh), which under CI=true counts as a failure like any other.
record() {
  times+=("$3 s wall, $4 s CPU  $1")
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
  local title="$1" t0=$SECONDS rc c0
  shift
  echo "[test] $title"
  cpu_now
  c0=$CPU
  "$@"
  rc=$?
  cpu_now
  record "$title" "$rc" "$((SECONDS - t0))" "$((CPU - c0))"
}
# beside <title> <function> [<title> <function>]...: starts stages that run one after the
# other in the background, beside the next stages of this shell, each one's output to a log
# that beside_wait shows when they have all ended. For stages that keep one core busy, beside
# a stage that leaves the other one idle; they share no files they write.
beside() {
  local k
  beside_titles=()
  for ((k = 1; k < $#; k += 2)); do
    beside_titles+=("${!k}")
    rm -f "$ROOT/build/test-beside.$((k / 2)).status"
    echo "[test] ${!k} (beside the next stage; its output follows when it ends)"
  done
  (
    CPU_FILE="$ROOT/build/test-cpu-beside.txt"
    i=0
    while [ $# -gt 0 ]; do
      t0=$SECONDS
      cpu_now
      c0=$CPU
      ("$2") > "$ROOT/build/test-beside.$i.log" 2>&1
      rc=$?
      cpu_now
      echo "$rc $((SECONDS - t0)) $((CPU - c0))" > "$ROOT/build/test-beside.$i.status"
      i=$((i + 1))
      shift 2
    done
  ) &
  beside_pid=$!
}
beside_wait() {
  local i rc wall cpu
  wait "$beside_pid"
  for i in "${!beside_titles[@]}"; do
    read -r rc wall cpu < "$ROOT/build/test-beside.$i.status" || { rc=1 wall=0 cpu=0; }
    echo "[test] ${beside_titles[$i]}:"
    cat "$ROOT/build/test-beside.$i.log"
    record "${beside_titles[$i]}" "$rc" "$wall" "$cpu"
  done
}

step "ctest (build/host)" ctest --test-dir "$ROOT/build/host" --output-on-failure --no-tests=error -j"$JOBS"
# ctest lists skipped tests without their reason; tests/RunTest.cmake logged it
grep -h "^ATTEKF-SKIP:" "$ROOT/build/host/Testing/Temporary/LastTest.log" 2>/dev/null | sed 's/^/[test] ctest /'
step "Cortex-M builds under QEMU (scripts/test_target.sh)" "$ROOT/scripts/test_target.sh"
# Beside pytest, which keeps one core busy (one process; the HIL's guests have one virtual
# CPU), two stages that keep the other one busy, held to one job each:
# - the pip package as a user gets it: sdist -> platform wheel (CMake) -> a fresh virtual
#   environment outside the repository without a C compiler, numpy alone then the extras, every
#   command and the Python API there (tests/package/);
# - static analysis (docs/reliability.md), in build/static.
package_stage() {
  CMAKE_BUILD_PARALLEL_LEVEL=1 "$ROOT/.venv/bin/python" -m pytest "$ROOT/tests/package" -q -ra -p no:cacheprovider
}
static_stage() {
  ATTEKF_JOBS=1 "$ROOT/scripts/static_analysis.sh"
}
beside "Python package: its wheel in a fresh virtual environment without a compiler (tests/package)" package_stage \
       "static analysis: cppcheck + clang-tidy (scripts/static_analysis.sh)" static_stage
step "pytest" "$ROOT/.venv/bin/python" -m pytest "$ROOT/tests/python" -q -ra --durations=15
beside_wait

# Reliability (docs/reliability.md): the ctest under ASan + UBSan, valgrind on the node, a
# short fuzz run of every target (scripts/fuzz.sh --time 3600 for a long one).
step "ctest under ASan + UBSan (scripts/test_sanitizers.sh)" "$ROOT/scripts/test_sanitizers.sh"
step "valgrind memcheck on attekf-node (scripts/test_valgrind.sh)" "$ROOT/scripts/test_valgrind.sh"
step "fuzzing, 30 s per target, mutation seed 1 (scripts/fuzz.sh)" "$ROOT/scripts/fuzz.sh" --time 30 --seed 1

cpu_now
echo "[test] time per stage (total $SECONDS s wall, $((CPU - cpu0)) s CPU; load average now: $(cut -d' ' -f1-3 /proc/loadavg)):"
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
