#!/usr/bin/env bash
# valgrind memcheck on the estimator node (firmware/app/attekf-node), docs/reliability.md:
#   1. replay through the virtual backend of a simulated 20 s recording (magnetic
#      disturbance, linear acceleration) with faults injected into the frame log: frames
#      dropped, duplicated, swapped, wrong length, unknown ids, a 3 s pause of the bus
#      (input stale, heartbeats);
#   2. the same replay with DroneCAN out (Solution, NodeStatus), and a DroneCAN session through
#      the virtual backend: RawIMU in, every service asked (the dronecan package encodes them),
#      the parameters saved to a file;
#   3. live mode on an interface that does not exist (open failure path, clean exit).
# Fails on any memcheck error or definite/indirect leak (--error-exitcode=99), on any other
# exit status than the expected one (replay 0, live mode 1) and on a missing statistics file.
# Without valgrind: fails under CI=true, else skipped (exit 77, scripts/prereq.sh).
#
#   ./scripts/test_valgrind.sh [BUILD_DIR]    default build/host (scripts/setup.sh builds it)
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="${1:-$ROOT/build/host}"
NODE="$BUILD/firmware/app/attekf-node"
PY="$ROOT/.venv/bin/python"
# shellcheck source=scripts/prereq.sh
. "$ROOT/scripts/prereq.sh"
attekf_require valgrind valgrind
[ -x "$NODE" ] || { echo "[valgrind] $NODE missing: build first" >&2; exit 1; }
WORK="$(mktemp -d "${TMPDIR:-/tmp}/attekf-valgrind.XXXXXX")"
trap 'rm -rf "$WORK"' EXIT
VG=(valgrind --tool=memcheck --error-exitcode=99 --leak-check=full --show-leak-kinds=definite,indirect
    --errors-for-leak-kinds=definite,indirect --track-origins=yes -q)

"$PY" -m attekf sim -q "$WORK/rec.csv" --duration 20 --rate 200 --seed 5 --lin-acc 3 \
      --mag-disturbance 30 || exit 1
"$PY" -m attekf replay -q "$WORK/rec.csv" --to-log "$WORK/clean.log" || exit 1
"$PY" - "$WORK/clean.log" "$WORK/faulty.log" <<'PYEOF' || { echo "[valgrind] fault injection failed" >&2; exit 1; }
import random, sys
src, dst = sys.argv[1:3]
lines = open(src).read().splitlines()
rng = random.Random(7)
out, shift = [], 0.0
for i, line in enumerate(lines):
    ts, chan, frame, *tail = line.split()            # candump -L, optionally " T"/" R"
    tail = (" " + " ".join(tail)) if tail else ""
    t = float(ts.strip("()")) + shift
    if i == len(lines) // 2:
        shift = 3.0                                  # the bus pauses 3 s: input stale
    u = rng.random()
    if u < 0.01:
        continue                                     # dropped
    rec = f"({t:.6f}) {chan} {frame}{tail}"
    out.append(rec)
    if u < 0.02:
        out.append(rec)                              # duplicated
    elif u < 0.03 and len(out) > 1:
        out[-1], out[-2] = out[-2], out[-1]          # swapped (times kept in order below)
    elif u < 0.035:
        out.append(f"({t:.6f}) {chan} 7E5#0102{tail}")  # unknown id
    elif u < 0.04:
        fid, data = frame.split("#")
        out.append(f"({t:.6f}) {chan} {fid}#{data[:8]}{tail}")  # wrong length
# keep time stamps non-decreasing after the swaps
ts_sorted = sorted(float(l.split()[0].strip("()")) for l in out)
out = [f"({t:.6f}) " + l.split(" ", 1)[1] for t, l in zip(ts_sorted, out)]
open(dst, "w").write("\n".join(out) + "\n")
PYEOF
status=0
"${VG[@]}" "$NODE" --replay "$WORK/faulty.log" -o "$WORK/out.log" --stats "$WORK/stats.json" -l error
rc=$?
if [ $rc -ne 0 ]; then echo "[valgrind] replay: exit $rc" >&2; status=1; fi
"${VG[@]}" "$NODE" --replay "$WORK/faulty.log" -o "$WORK/out_dc.log" --protocol dronecan --input dbc \
  --stats "$WORK/stats_dc.json" -l error
rc=$?
if [ $rc -ne 0 ]; then echo "[valgrind] DroneCAN replay: exit $rc" >&2; status=1; fi
"$PY" - "$ROOT" "$WORK/rec.csv" "$WORK/dronecan.log" <<'PYEOF' || { echo "[valgrind] DroneCAN session failed" >&2; exit 1; }
import sys
root, rec_csv, out = sys.argv[1:4]
sys.path.insert(0, root + "/tests/python")
import dcanutil, dronecan
from attekf.io import read_recording
rec = read_recording(rec_csv).slice(0, 600)
frames = dcanutil.raw_imu_frames(rec.t, rec.gyr, rec.acc, rec.mag, 21)
P = dronecan.uavcan.protocol.param
reqs = [dronecan.uavcan.protocol.GetNodeInfo.Request(), P.GetSet.Request(name="gyro_noise"),
        P.GetSet.Request(name="mag_declination", value=P.Value(real_value=0.1)),
        P.GetSet.Request(name="accel_lpf_order", value=P.Value(integer_value=1)),
        P.GetSet.Request(name="no.such"), P.GetSet.Request(index=3),
        P.ExecuteOpcode.Request(opcode=0), dronecan.uavcan.protocol.RestartNode.Request(magic_number=0xACCE551B1E)]
for k, r in enumerate(reqs):
    frames += dcanutil.transfer_frames(r, 1.0 + 0.2 * k, 127, k, dest=100)
dcanutil.write_candump(out, frames)
PYEOF
"${VG[@]}" "$NODE" --replay "$WORK/dronecan.log" -o "$WORK/out_session.log" --protocol dronecan --node-id 100 \
  --params "$WORK/node.params" --stats "$WORK/stats_session.json" -l error
rc=$?
if [ $rc -ne 0 ] || ! grep -q "accel_lpf_order 1" "$WORK/node.params"; then
  echo "[valgrind] DroneCAN session: exit $rc, or the parameters were not saved" >&2; status=1
fi
"${VG[@]}" "$NODE" --interface attekf-none0 --duration 1 -l error 2>"$WORK/live.err"
rc=$?
# the interface does not exist: the node must say so and exit 1 (99: a memcheck error)
if [ $rc -ne 1 ] || ! grep -q "cannot open CAN interface" "$WORK/live.err"; then
  cat "$WORK/live.err" >&2; echo "[valgrind] live mode: exit $rc, expected 1 with 'cannot open CAN interface'" >&2; status=1
fi
outputs="$(wc -l < "$WORK/out.log")" || status=1
"$PY" -c "import json,sys; c=json.load(open(sys.argv[1]))[\"counters\"]; print(\"[valgrind] node counters:\", \", \".join(f\"{k} {v}\" for k,v in c.items() if v))" "$WORK/stats.json" \
  || { echo "[valgrind] replay: no readable counters in $WORK/stats.json" >&2; status=1; }
echo "[valgrind] attekf-node replay ($(wc -l < "$WORK/faulty.log") frames in, $outputs out) and live-mode start:" \
     "$([ $status -eq 0 ] && echo 'no memcheck errors, no leaks' || echo FAILED)"
exit $status
