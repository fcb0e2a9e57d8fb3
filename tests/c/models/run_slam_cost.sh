#!/usr/bin/env bash
# Instruction counts of the EKF-SLAM operations versus the number of mapped landmarks k
# (state dimension n = 3 + 2k), measured with callgrind on bench_slam_cost (see its header).
# Not part of the test suite: a benchmark whose numbers are recorded in docs/models.md.
#
#   tests/c/models/run_slam_cost.sh [build-dir] [f|d]     (defaults: build/host, f)
#
# Prints, per k: instructions per call of slam_predict, of slam_observe on a mapped landmark
# (of which inside ekf_update_scalar, the core's two scalar updates), of a landmark
# augmentation, and of a dense textbook prediction (F formed, P <- F P F^T) for comparison.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)"
BUILD="${1:-$ROOT/build/host}"
SCALAR="${2:-f}"
BENCH="$BUILD/tests/c/models/bench_slam_cost_$SCALAR"
ITER=64

if ! command -v valgrind >/dev/null 2>&1; then
  echo "run_slam_cost.sh: valgrind not found (scripts/setup.sh installs it)" >&2
  exit 1
fi
if [ ! -x "$BENCH" ]; then
  echo "run_slam_cost.sh: $BENCH not built (cmake --build $BUILD)" >&2
  exit 1
fi
MAXK="$("$BENCH" 2>&1 | sed -n 's/.*landmarks 1\.\.\([0-9]*\).*/\1/p' || true)"

# instructions collected inside <function> (inclusive) for one run of the bench
count() { # <toggle-function> <phase> <k> <iterations>
  valgrind --tool=callgrind --callgrind-out-file=/dev/null --toggle-collect="$1" \
    "$BENCH" "$2" "$3" "$4" 2>&1 >/dev/null | sed -n 's/.*Collected : \([0-9]*\).*/\1/p'
}

printf "%3s %3s %14s %14s %20s %14s %16s\n" k n predict observe "(ekf_update_scalar)" augment dense_predict
for k in $(seq 1 "$MAXK"); do
  n=$((3 + 2 * k))
  pr=$(count bench_measured predict "$k" $ITER)
  ob=$(count bench_measured observe "$k" $ITER)
  # the set-up calls ekf_update_scalar too: count two run lengths and take the difference
  up=$(( $(count ekf_update_scalar observe "$k" $((2 * ITER))) - $(count ekf_update_scalar observe "$k" $ITER) ))
  au="-"
  if [ "$k" -gt 1 ]; then au=$(count bench_measured augment "$((k - 1))" 1); fi
  dp=$(count bench_measured dense_predict "$k" $ITER)
  printf "%3d %3d %14d %14d %20d %14s %16d\n" "$k" "$n" $((pr / ITER)) $((ob / ITER)) $((up / ITER)) "$au" \
    $((dp / ITER))
done
echo "(instructions per call, $SCALAR build; augment at k = adding the k-th landmark)"
