#!/usr/bin/env bash
# Fuzzing (tests/fuzz/README.md, docs/reliability.md): builds the libFuzzer targets with
# clang (ASan + UBSan, every finding fatal) and runs them, all at once, for a fixed time.
#
#   ./scripts/fuzz.sh                  every target, 60 s each (what the test suite runs)
#   ./scripts/fuzz.sh --time 3600      a long run (an hour per target)
#   ./scripts/fuzz.sh --targets "fuzz_att_f fuzz_att_d" --time 600 --jobs 2
#   ./scripts/fuzz.sh --seed 0         random mutation seed (default 1: the suite's run is
#                                      repeatable; a finding reproduces with the same seed)
#
# Targets: fuzz_att_f, fuzz_att_d, fuzz_att_x (estimator: float, double, fixed point), fuzz_can (the node's CAN
# protocols, DBC and DroneCAN, + the node), fuzz_socketcan (SocketCAN receive path), fuzz_candump (the node's candump log lines),
# fuzz_parsers (Python file parsers, atheris).
# Default: all but fuzz_att_d. --jobs: libFuzzer worker processes per target (default 1).
# Each target starts from its committed seeds (tests/fuzz/corpus/<target>) plus what earlier
# runs found (build/fuzz/corpus/<target>, not committed). A crash, an invariant failure or
# a sanitizer report fails the script and leaves the input in build/fuzz/artifacts/<target>/;
# reproduce with: build/fuzz/<target> <that file>. A target that ran no input fails too.
# Without clang, libFuzzer (libclang-rt) or atheris: fails under CI=true, else skipped (exit 77,
# scripts/prereq.sh).
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
TIME=60
TARGETS="fuzz_att_f fuzz_att_x fuzz_can fuzz_socketcan fuzz_candump fuzz_parsers"
WORKERS=1
SEED=1
while (($#)); do
  case "$1" in
    --time) TIME="$2"; shift 2 ;;
    --targets) TARGETS="$2"; shift 2 ;;
    --jobs) WORKERS="$2"; shift 2 ;;
    --seed) SEED="$2"; shift 2 ;;
    -h|--help) sed -n '2,20p' "$0"; exit 0 ;;
    *) echo "fuzz.sh: unknown option '$1' (see --help)" >&2; exit 2 ;;
  esac
done
OUT="$ROOT/build/fuzz"
log() { printf '[fuzz] %s\n' "$*"; }
# shellcheck source=scripts/prereq.sh
. "$ROOT/scripts/prereq.sh"
attekf_require fuzz clang
mkdir -p "$OUT"
# libFuzzer is clang's runtime package (libclang-rt-*-dev), separate from clang itself.
printf 'int LLVMFuzzerTestOneInput(const unsigned char *d, unsigned long n) { (void)d; (void)n; return 0; }\n' \
  > "$OUT/probe.c"
clang -fsanitize=fuzzer "$OUT/probe.c" -o "$OUT/probe" >"$OUT/probe.log" 2>&1 \
  || attekf_missing fuzz "libFuzzer (clang -fsanitize=fuzzer) cannot link: $(tail -n 1 "$OUT/probe.log")"
case " $TARGETS " in
  *" fuzz_parsers "*)
    "$ROOT/.venv/bin/python" -c "import atheris" 2>/dev/null || attekf_missing fuzz "atheris (Python) not installed" ;;
esac

c_targets=()
for t in $TARGETS; do [ "$t" = fuzz_parsers ] || c_targets+=("$t"); done
if ((${#c_targets[@]})); then
  t0=$SECONDS
  cmake -S "$ROOT/tests/fuzz" -B "$OUT" -G Ninja -DCMAKE_C_COMPILER=clang >/dev/null || exit 1
  cmake --build "$OUT" --target "${c_targets[@]}" >/dev/null || { echo "[fuzz] build failed" >&2; exit 1; }
  log "built ${c_targets[*]} in $((SECONDS - t0)) s"
fi

pids=(); names=()
for t in $TARGETS; do
  seeds="$ROOT/tests/fuzz/corpus/${t%_[fdx]}"
  work="$OUT/corpus/$t"
  art="$OUT/artifacts/$t/"
  mkdir -p "$work" "$art"
  opts=(-max_total_time="$TIME" -seed="$SEED" -print_final_stats=1 -artifact_prefix="$art" -timeout=10 -rss_limit_mb=2048)
  if [ "$WORKERS" -gt 1 ]; then opts+=(-fork="$WORKERS" -ignore_crashes=0); fi
  if [ "$t" = fuzz_parsers ]; then
    cmd=("$ROOT/.venv/bin/python" "$ROOT/tests/fuzz/fuzz_parsers.py")
    opts+=(-max_len=4096)
  else
    cmd=("$OUT/$t")
  fi
  ( cd "$OUT" && exec "${cmd[@]}" "${opts[@]}" "$work" "$seeds" ) > "$OUT/$t.log" 2>&1 &
  pids+=($!); names+=("$t")
done
log "running ${names[*]} for $TIME s"
status=0
for i in "${!pids[@]}"; do
  t="${names[$i]}"
  if wait "${pids[$i]}"; then rc=0; else rc=$?; fi
  execs="$(grep -Eo 'stat::number_of_executed_units: [0-9]+' "$OUT/$t.log" | awk '{s += $2} END {print s + 0}')"
  if [ "$execs" = 0 ]; then execs="$(grep -Eo '^Done [0-9]+ runs' "$OUT/$t.log" | awk '{s += $2} END {print s + 0}')"; fi
  cov="$(grep -Eo 'cov: [0-9]+' "$OUT/$t.log" | tail -1)"
  if [ "$rc" -eq 0 ] && [ "$execs" = 0 ]; then
    status=1
    log "$t: FAILED: no input was executed; log $OUT/$t.log"
  elif [ "$rc" -ne 0 ]; then
    status=1
    log "$t: FAILED (exit $rc) after $execs executions; log $OUT/$t.log, input in $OUT/artifacts/$t/"
    grep -E "invariant failed|runtime error|ERROR: |Uncaught Python exception|Error|error" "$OUT/$t.log" | head -5 >&2
  else
    log "$t: $execs executions, $cov, no findings"
  fi
done
exit "$status"
