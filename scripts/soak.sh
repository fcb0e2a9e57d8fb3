#!/usr/bin/env bash
# Long soak of the estimator (tests/soak/soak.c, docs/reliability.md "Soak").
#
#   ./scripts/soak.sh [--steps N] [--flights K] [--scalars "f d"] [--jobs J] [--bound-deg B] [--settle-s S]
#
# Runs K independent simulated flights per scalar type (seeds 1..K), each a continuous run of
# N steps at 1 kHz (default N = 10^8 = 27.8 h of flight, K = 1, scalars f), J at a time
# (default: the number of cores). Every step is checked (see soak.c); the script fails if any
# flight fails. --bound-deg: attitude-error bound in benign time (default 30; 0 = report
# only), benign from --settle-s seconds after the last fault on (default 15). Results:
# build/soak/soak-<scalar>-<seed>.txt, summary on stdout.
# Time on this 2-core machine: about 3.5 s per 10^6 steps per core (float).
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
STEPS=100000000; FLIGHTS=1; SCALARS="f"; JOBS="$(nproc)"; BOUND=30; SETTLE=15
while (($#)); do
  case "$1" in
    --steps) STEPS="$2"; shift 2 ;;
    --flights) FLIGHTS="$2"; shift 2 ;;
    --scalars) SCALARS="$2"; shift 2 ;;
    --jobs) JOBS="$2"; shift 2 ;;
    --bound-deg) BOUND="$2"; shift 2 ;;
    --settle-s) SETTLE="$2"; shift 2 ;;
    -h|--help) sed -n '2,14p' "$0"; exit 0 ;;
    *) echo "soak.sh: unknown option '$1' (see --help)" >&2; exit 2 ;;
  esac
done
OUT="$ROOT/build/soak"
PY="$ROOT/.venv/bin/python"; [ -x "$PY" ] || PY=python3
cmake -S "$ROOT" -B "$OUT" -G Ninja -DCMAKE_BUILD_TYPE=Release -DPython3_EXECUTABLE="$PY" >/dev/null || exit 1
targets=(); for s in $SCALARS; do targets+=("attekf-soak_$s"); done
cmake --build "$OUT" --target "${targets[@]}" >/dev/null || { echo "[soak] build failed" >&2; exit 1; }

echo "[soak] $FLIGHTS flight(s) x $STEPS steps x scalars '$SCALARS', $JOBS at a time"
start=$SECONDS
status=0
pids=(); names=()
for s in $SCALARS; do
  for seed in $(seq 1 "$FLIGHTS"); do
    while (( $(jobs -rp | wc -l) >= JOBS )); do wait -n; done
    "$OUT/tests/c/attekf-soak_$s" --steps "$STEPS" --seed "$seed" --bound-deg "$BOUND" --settle-s "$SETTLE" > "$OUT/soak-$s-$seed.txt" 2>&1 &
    pids+=($!); names+=("$s-$seed")
  done
done
for i in "${!pids[@]}"; do
  if ! wait "${pids[$i]}"; then status=1; fi
  printf '[soak] %s: %s\n' "${names[$i]}" "$(tail -n 1 "$OUT/soak-${names[$i]}.txt")"
done
echo "[soak] $(( SECONDS - start )) s"
if [ "$status" -ne 0 ]; then echo "[soak] FAILED" >&2; fi
exit "$status"
