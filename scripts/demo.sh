#!/usr/bin/env bash
# The main job: simulate two recordings with known truth (one undisturbed, one with
# linear-acceleration and magnetic-disturbance episodes), run the C estimator over them
# through the Python binding, and write a table and plots.
#
#   ./scripts/demo.sh [OUT_DIR]      default OUT_DIR: out/demo
#
# Writes OUT_DIR/recordings/*.csv, OUT_DIR/table.txt, OUT_DIR/results.json and
# OUT_DIR/<trial>.png, and prints the table. Needs scripts/setup.sh to have run (venv and
# build/host). Takes a few seconds.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="${1:-$ROOT/out/demo}"
ATTEKF="$ROOT/.venv/bin/attekf"
if [ ! -x "$ATTEKF" ]; then
  echo "demo.sh: $ATTEKF not found: run ./scripts/setup.sh first" >&2
  exit 1
fi

echo "[demo] simulating recordings into $OUT/recordings"
rm -rf "$OUT/recordings"
"$ATTEKF" sim "$OUT/recordings/undisturbed.csv" --duration 60 --rate 100 --seed 1
"$ATTEKF" sim "$OUT/recordings/disturbed.csv" --duration 60 --rate 100 --seed 2 \
  --lin-acc 3 --mag-disturbance 30
echo "[demo] running the C estimator (float build) and scoring against the truth"
"$ATTEKF" eval "$OUT/recordings" --out "$OUT" --quiet
echo "[demo] plots: $OUT/undisturbed.png $OUT/disturbed.png; JSON: $OUT/results.json"
