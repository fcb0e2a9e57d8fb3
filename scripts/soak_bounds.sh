#!/usr/bin/env bash
# The soak (tests/soak/soak.c) with every setting at its lower and at its upper bound, one at
# a time, the others at their defaults (soak --setting-bound; docs/reliability.md, "Settings
# at their bounds"). Every step is checked as in the soak; the attitude error is reported, not
# bounded (--bound-deg 0: a bound setting may legitimately make the estimate worse).
#
#   ./scripts/soak_bounds.sh [--build DIR] [--scalars "f d x"] [--steps N] [--seed S]
#
# --build: a configured build directory with the soak executables (default build/host;
# build/host-asan runs them under ASan + UBSan, every finding fatal). Default 100000 steps
# (100 s of flight) per bound, seed 1. Fails if any run fails; prints one line per failure
# and per run with guard repairs, and a summary per scalar type.
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="$ROOT/build/host"; SCALARS="f d x"; STEPS=100000; SEED=1
while (($#)); do
  case "$1" in
    --build) BUILD="$2"; shift 2 ;;
    --scalars) SCALARS="$2"; shift 2 ;;
    --steps) STEPS="$2"; shift 2 ;;
    --seed) SEED="$2"; shift 2 ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    *) echo "soak_bounds.sh: unknown option '$1' (see --help)" >&2; exit 2 ;;
  esac
done
targets=(); for s in $SCALARS; do targets+=("attekf-soak_$s"); done
cmake --build "$BUILD" --target "${targets[@]}" >/dev/null || { echo "[soak_bounds] build failed in $BUILD" >&2; exit 1; }
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1"
status=0
start=$SECONDS
for s in $SCALARS; do
  exe="$BUILD/tests/c/attekf-soak_$s"
  runs=0; failed=0; repairs=0
  for name in $("$exe" --list-settings); do
    for b in lo hi; do
      out="$("$exe" --steps "$STEPS" --seed "$SEED" --bound-deg 0 --setting-bound "$name:$b" --quiet 2>&1)"
      rc=$?
      runs=$((runs + 1))
      r="$(printf '%s\n' "$out" | sed -n 's/.*cov_repairs=\([0-9]*\).*/\1/p' | tail -n 1)"
      repairs=$((repairs + ${r:-0}))
      [ "${r:-0}" -gt 0 ] && printf '[soak_bounds] %s %s:%s: %s guard repairs\n' "$s" "$name" "$b" "$r"
      if [ "$rc" -ne 0 ] || ! printf '%s\n' "$out" | grep -q "result=PASS"; then
        failed=$((failed + 1)); status=1
        printf '[soak_bounds] %s %s:%s FAILED: %s\n' "$s" "$name" "$b" "$(printf '%s\n' "$out" | tail -n 3 | tr '\n' ' ')"
      fi
    done
  done
  printf '[soak_bounds] %s: %d runs of %s steps, %d failed, %d guard repairs in all\n' "$s" "$runs" "$STEPS" "$failed" "$repairs"
done
echo "[soak_bounds] $(( SECONDS - start )) s"
exit $status
