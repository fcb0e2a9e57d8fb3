#!/usr/bin/env bash
# One hardware-in-loop run on a CAN interface (docs/hil.md):
#   1. start attekf-node on IFACE and `attekf record` (logs the whole bus),
#   2. wait until both listen, replay INPUT with `attekf replay` (paced at recorded time),
#      optionally taking the interface down and up again in the middle,
#   3. let the last outputs arrive, stop both, keep everything in OUTDIR:
#        node.json    node counters and node-side latency (attekf-node --stats)
#        node.log     node's log
#        bus.log      every frame on the bus (candump format)
#        record.json  recorder's view: frames, sequence gaps, bus latency (attekf record --stats)
#        replay.json  what was sent and what failed (attekf replay --stats)
#        bounce.log   when the interface went down/up (with --bounce: down when the replay
#                     reaches AFTER_S of the stream, up DOWN_S later, and not before the
#                     replay reaches AFTER_S + DOWN_S)
#        ifstats.txt  the interface's kernel statistics before the replay and at the end
#                     (rx_dropped counts frames the kernel dropped, e.g. sent as it went down)
#
#   tests/vm/hil_scenario.sh OUTDIR IFACE INPUT [--speed X] [--bounce AFTER_S,DOWN_S]
#                             [--node-arg ARG]...
#
# Runs wherever IFACE exists: a real can0, a vcan0 on a kernel with CAN, or inside a guest of
# tests/vm/vcan_run.py (user-mode Linux or QEMU). Environment: ATTEKF_NODE (node binary, default
# build/host/firmware/app/attekf-node), ATTEKF_PYTHON (interpreter with the attekf package,
# default .venv/bin/python). Exit status: 0 if every step ran (the checks are the tests' job),
# 1 if a step failed (its log says why), 2 usage.
set -u
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
usage() { sed -n '2,24p' "$0"; exit 2; }
[ $# -ge 3 ] || usage
OUT="$1"; IFACE="$2"; INPUT="$3"; shift 3
SPEED=1; BOUNCE=""; NODE_ARGS=()
while [ $# -gt 0 ]; do
  case "$1" in
    --speed) SPEED="$2"; shift 2 ;;
    --bounce) BOUNCE="$2"; shift 2 ;;
    --node-arg) NODE_ARGS+=("$2"); shift 2 ;;
    -h|--help) usage ;;
    *) echo "hil_scenario: unknown option $1" >&2; exit 2 ;;
  esac
done
NODE="${ATTEKF_NODE:-$ROOT/build/host/firmware/app/attekf-node}"
PY="${ATTEKF_PYTHON:-$ROOT/.venv/bin/python}"
[ -x "$NODE" ] || { echo "hil_scenario: $NODE not built" >&2; exit 1; }
[ -x "$PY" ] || { echo "hil_scenario: no Python at $PY" >&2; exit 1; }
mkdir -p "$OUT"
rm -f "$OUT"/node.ready "$OUT"/record.ready "$OUT"/replay.started "$OUT"/replay.down "$OUT"/replay.up \
  "$OUT"/replay.done

"$NODE" -i "$IFACE" --ready-file "$OUT/node.ready" --stats "$OUT/node.json" "${NODE_ARGS[@]}" \
  > "$OUT/node.log" 2>&1 &
NODE_PID=$!
# --idle: the recorder stops by itself once the bus has been quiet for 2 s after the node
# stopped, so it keeps what it had not read yet when it runs slower than the bus (emulation).
"$PY" -m attekf record -q -i socketcan -c "$IFACE" -o "$OUT/bus.log" --stats "$OUT/record.json" \
  --ready-file "$OUT/record.ready" --idle 2 > "$OUT/record.log" 2>&1 &
REC_PID=$!

# Wait (at most 60 s: Python imports are slow under UML) until both listen.
for _ in $(seq 1 1200); do
  [ -f "$OUT/node.ready" ] && [ -f "$OUT/record.ready" ] && break
  kill -0 "$NODE_PID" 2>/dev/null || break
  kill -0 "$REC_PID" 2>/dev/null || break
  sleep 0.05
done
if ! [ -f "$OUT/node.ready" ] || ! [ -f "$OUT/record.ready" ]; then
  echo "hil_scenario: node or recorder did not start (see $OUT/node.log, $OUT/record.log)" >&2
  kill "$NODE_PID" "$REC_PID" 2>/dev/null; wait
  exit 1
fi

ifstats() {   # one line: LABEL key=value ... from /sys/class/net/IFACE/statistics
  local line="$1" k
  for k in rx_packets rx_dropped tx_packets tx_dropped; do
    line="$line $k=$(cat "/sys/class/net/$IFACE/statistics/$k" 2>/dev/null || echo NA)"
  done
  echo "$line" >> "$OUT/ifstats.txt"
}
rm -f "$OUT/ifstats.txt"
ifstats start

BOUNCE_PID=""
MARK=()
if [ -n "$BOUNCE" ]; then
  # By the stream's time as well as the clock's: a replay that lags (a loaded machine) would
  # otherwise meet the outage elsewhere in the stream, and lose more of it as it catches up;
  # and an `ip` that starts late still leaves the interface down DOWN_S. The waits start no
  # process (`read -t` on a pipe nobody writes is the pause) and `ip` comes before the time
  # is logged: in a guest with one virtual CPU shared with the replay and the node, each
  # process started costs up to a second on a loaded host.
  AFTER="${BOUNCE%,*}"; DOWN="${BOUNCE#*,}"
  MARK=(--mark "$AFTER:$OUT/replay.down" --mark "$(awk -v a="$AFTER" -v d="$DOWN" 'BEGIN { print a + d }'):$OUT/replay.up")
  (
    coproc PAUSER { exec sleep 3600; }
    trap 'kill "$PAUSER_PID" 2>/dev/null' EXIT
    pause() {   # read's time-out on a pipe nobody writes; sleep if that pipe is gone
      read -r -t "$1" -u "${PAUSER[0]}" 2> /dev/null
      [ $? -gt 128 ] || sleep "$1"
    }
    wait_for() { until [ -f "$1" ]; do [ -f "$OUT/replay.done" ] && return 1; pause 0.01; done; }
    wait_for "$OUT/replay.down" || exit 0
    ip link set "$IFACE" down; echo "down $EPOCHREALTIME"
    pause "$DOWN"
    wait_for "$OUT/replay.up"
    ip link set "$IFACE" up; echo "up $EPOCHREALTIME"
  ) > "$OUT/bounce.log" 2>&1 &
  BOUNCE_PID=$!
fi

"$PY" -m attekf replay -q "$INPUT" -i socketcan -c "$IFACE" --speed "$SPEED" \
  --stats "$OUT/replay.json" --started-file "$OUT/replay.started" "${MARK[@]}" > "$OUT/replay.log" 2>&1
REPLAY_RC=$?
touch "$OUT/replay.done"
[ -n "$BOUNCE_PID" ] && wait "$BOUNCE_PID"

sleep 0.5   # the outputs of the last samples
kill -TERM "$NODE_PID"
wait "$NODE_PID"; NODE_RC=$?
for _ in $(seq 1 1200); do kill -0 "$REC_PID" 2>/dev/null || break; sleep 0.1; done
kill -INT "$REC_PID" 2>/dev/null
wait "$REC_PID"; REC_RC=$?
ifstats end
echo "replay=$REPLAY_RC node=$NODE_RC record=$REC_RC" > "$OUT/status"
[ "$REPLAY_RC" -eq 0 ] && [ "$NODE_RC" -eq 0 ] && [ "$REC_RC" -eq 0 ]
