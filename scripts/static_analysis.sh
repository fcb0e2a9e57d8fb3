#!/usr/bin/env bash
# Static analysis of firmware/ and hal/: cppcheck and clang-tidy (Debian packages), with the
# committed configuration (.cppcheck-suppressions, .clang-tidy). Zero findings or it fails.
#
#   ./scripts/static_analysis.sh [BUILD_DIR]    default build/static
#
# The file list is every firmware/ and hal/ source of the host build (compile_commands.json
# of a configure-only build; float, double and fixed-point builds of the core each count),
# plus, for cppcheck, the Cortex-M-only sources of firmware/target (not in a host build).
# docs/reliability.md lists what is checked and every suppression.
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
OUT="${1:-$ROOT/build/static}"
JOBS="$(nproc)"
log() { printf '[static] %s\n' "$*"; }

# shellcheck source=scripts/prereq.sh
. "$ROOT/scripts/prereq.sh"
attekf_require static cppcheck run-clang-tidy clang-tidy

PY="$ROOT/.venv/bin/python"; [ -x "$PY" ] || PY=python3
cmake -S "$ROOT" -B "$OUT" -G Ninja -DCMAKE_EXPORT_COMPILE_COMMANDS=ON -DATTEKF_BUILD_TESTS=OFF \
      -DPython3_EXECUTABLE="$PY" >/dev/null 2>&1 || { echo "[static] configure failed" >&2; exit 1; }
mkdir -p "$OUT/db" "$OUT/cppcheck-cache"
# The filter fails (and with it the script) on an unreadable database or one without any
# firmware/ or hal/ source: an empty list would make both analysers pass having read nothing.
python3 - "$OUT/compile_commands.json" "$OUT/db/compile_commands.json" "$ROOT" <<'PYEOF' || { echo "[static] compile database filter failed" >&2; exit 1; }
import json, sys
src, dst, root = sys.argv[1:4]
keep = [e for e in json.load(open(src))
        if e["file"].startswith((root + "/firmware/", root + "/hal/"))]
if not keep:
    sys.exit(f"[static] {src}: no firmware/ or hal/ source in the compile database")
json.dump(keep, open(dst, "w"), indent=1)
# clang-tidy: each file once (the float build where there is one: what ships); its
# analysis is slow, and the scalar builds differ only in ekf_scalar.h's inline functions.
once = {}
for e in keep:
    if e["file"] not in once or "EKF_SCALAR_FLOAT" in e["command"]:
        once[e["file"]] = e
import os
os.makedirs(os.path.join(os.path.dirname(dst), "tidy"), exist_ok=True)
json.dump(list(once.values()), open(os.path.join(os.path.dirname(dst), "tidy", "compile_commands.json"), "w"), indent=1)
print(f"[static] {len(keep)} compile commands ({len(once)} files) from firmware/ and hal/")
PYEOF

status=0
t0=$SECONDS
log "cppcheck $(cppcheck --version | cut -d' ' -f2)"
CPPCHECK_OPTS=(--enable=warning,style,performance,portability --inline-suppr --error-exitcode=1 -q
               --suppressions-list="$ROOT/.cppcheck-suppressions")
cppcheck "${CPPCHECK_OPTS[@]}" --project="$OUT/db/compile_commands.json" \
         --cppcheck-build-dir="$OUT/cppcheck-cache" -j"$JOBS" || status=1
# Cortex-M-only sources (cross builds): analysed with the target's configuration.
CROSS=()
for f in firmware/target/*.c; do
  grep -q "\"file\": \"$ROOT/$f\"" "$OUT/db/compile_commands.json" || CROSS+=("$f")
done
if ((${#CROSS[@]})); then
  cppcheck "${CPPCHECK_OPTS[@]}" --std=c99 -DEKF_SCALAR_FLOAT=1 -D__arm__ -D__ARM_ARCH_7EM__ \
           -Ifirmware/ekf -Ifirmware/att -Ifirmware/app -Ifirmware/app/dbc -Ifirmware/app/dronecan -Ifirmware/target \
           -Ihal/include -Ihal/virtual "${CROSS[@]}" || status=1
fi
log "cppcheck done in $((SECONDS - t0)) s"

t0=$SECONDS
tidy_files="$(grep -c '"file"' "$OUT/db/tidy/compile_commands.json")"
if [ "${tidy_files:-0}" -eq 0 ]; then
  echo "[static] $OUT/db/tidy/compile_commands.json lists no file: clang-tidy would check nothing" >&2
  exit 1
fi
log "clang-tidy $(clang-tidy --version | sed -n 's/.*version \([0-9.]*\).*/\1/p' | head -1) ($tidy_files files)"
if ! run-clang-tidy -p "$OUT/db/tidy" -j"$JOBS" -quiet "$ROOT/(firmware|hal)/" > "$OUT/clang-tidy.log" 2>&1; then
  grep -E "(warning|error):" "$OUT/clang-tidy.log" | sort -u >&2
  echo "[static] clang-tidy reported findings (full log: $OUT/clang-tidy.log)" >&2
  status=1
fi
# run-clang-tidy logs one command line per file it ran on: all of the database, or a failure.
checked="$(grep -c -- ' -quiet ' "$OUT/clang-tidy.log")"
if [ "${checked:-0}" -ne "$tidy_files" ]; then
  echo "[static] clang-tidy ran on ${checked:-0} of $tidy_files files (log: $OUT/clang-tidy.log)" >&2
  status=1
fi
log "clang-tidy done in $((SECONDS - t0)) s"

if [ "$status" -eq 0 ]; then log "no findings"; else log "FINDINGS (see above)"; fi
exit "$status"
