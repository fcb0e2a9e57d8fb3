#!/usr/bin/env python3
"""Node CPU and bus load at 100, 200 and 400 Hz attitude output (docs/can_protocol.md, "Load").

For each protocol (our DBC, DroneCAN) and output rate: attekf-node on vcan0 inside a guest (the
vcan runner's first working backend: the host's CAN, user-mode Linux or QEMU), an IMU at 400 Hz
(a simulated recording as our DBC's frames, 4 per sample, played by can-utils' canplayer at their
times) for --duration s. Reported:

  * the node's CPU time (getrusage, user + system, in the guest) per second of the stream, in %
    of one CPU of the guest: an upper bound for real hardware (every system call is expensive
    in an emulated guest);
  * the same frames through the node's virtual backend on the host (attekf-node --replay, no
    emulator; REPEAT runs, their CPU time summed): CPU time per second of stream, reading the
    log and starting the process included;
  * the bus: the node's frames per second and bits per second (each frame's exact length on the
    wire: its stuff bits counted from its id, data and CRC-15, plus the 3-bit interframe space),
    and the whole bus (the IMU's frames too), in % of 500 kbit/s and 1 Mbit/s. The node's frames
    are those the host replay of the same IMU frames sends (the same code, deterministic; a
    candump in an emulated guest falls behind a bus this busy), their count checked against the
    live node's tx_frames.

Not a test: a measurement, printed as a Markdown table (--json for the raw numbers).

    scripts/node_load.py [--duration 10] [--rates 100,200,400] [--mode auto] [--json out.json]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IMU_RATE_HZ = 400.0
REPEAT = 20   # host replays per configuration (one lasts about the clock's accounting step)


def vcan_run_module():
    """The vcan runner (tests/vm/vcan_run.py, or hal/tools/vcan_run.py before it moved there)."""
    for p in (ROOT / "tests" / "vm" / "vcan_run.py", ROOT / "hal" / "tools" / "vcan_run.py"):
        if p.is_file():
            spec = importlib.util.spec_from_file_location("vcan_run", p)
            mod = importlib.util.module_from_spec(spec)
            sys.modules["vcan_run"] = mod
            spec.loader.exec_module(mod)
            return mod
    raise SystemExit("node_load: the vcan runner (tests/vm/vcan_run.py) is missing")


# ---- CAN frame length on the wire ---------------------------------------------------------
def _crc15(bits):
    crc = 0
    for b in bits:
        nxt = b ^ ((crc >> 14) & 1)
        crc = (crc << 1) & 0x7FFF
        if nxt:
            crc ^= 0x4599
    return crc


def frame_bits(can_id: int, extended: bool, data: bytes) -> int:
    """Bits a classic data frame takes on the bus: SOF .. EOF with its stuff bits, plus the
    3-bit interframe space."""
    def bits(value, n):
        return [(value >> (n - 1 - i)) & 1 for i in range(n)]
    dlc = len(data)
    if extended:
        head = [0] + bits(can_id >> 18, 11) + [1, 1] + bits(can_id & 0x3FFFF, 18) + [0, 0, 0]  # SRR IDE .. RTR r1 r0
    else:
        head = [0] + bits(can_id, 11) + [0, 0, 0]                                                # RTR IDE r0
    body = head + bits(dlc, 4) + [b for byte in data for b in bits(byte, 8)]
    stuffed = body + bits(_crc15(body), 15)
    stuff, run, last = 0, 0, None
    for b in stuffed:                  # after 5 equal bits a complement is inserted (and counts)
        if b == last:
            run += 1
        else:
            run, last = 1, b
        if run == 5:
            stuff += 1
            run, last = 1, 1 - b
    return len(stuffed) + stuff + 1 + 2 + 7 + 3    # CRC delimiter, ACK slot + delimiter, EOF, IFS


def read_candump(path: Path):
    out = []
    for line in open(path):
        parts = line.split()
        if len(parts) < 3 or not parts[0].startswith("("):
            continue
        ident, data = parts[2].split("#", 1)
        out.append((float(parts[0][1:-1]), int(ident, 16), bytes.fromhex(data), len(ident) > 3))
    return out


# ---- the runs -------------------------------------------------------------------------------
def imu_log(path: Path, duration: float) -> int:
    """A simulated recording at IMU_RATE_HZ as our DBC's frames, in candump's format. Returns
    the number of frames."""
    sys.path.insert(0, str(ROOT / "host_tools"))
    from attekf import canproto
    from attekf.sim import SimConfig, simulate
    rec = simulate(SimConfig(duration_s=duration, rate_hz=IMU_RATE_HZ, seed=41))
    enc = canproto.encode_samples(rec.t, rec.gyr, rec.acc, rec.mag)
    with open(path, "w") as fh:
        for t, i, d in zip(enc.t, enc.ids, enc.data):
            fh.write(f"({1.0 + t:.6f}) vcan0 {int(i):03X}#{bytes(d).hex().upper()}\n")
    return len(enc)


def guest_script(node: Path, imu: Path, work: Path, runs) -> str:
    q = shlex.quote
    lines = ["set -u"]
    for name, protocol, rate in runs:
        d = work / name
        lines += [
            f"mkdir -p {q(str(d))}",
            f"{q(str(node))} -i vcan0 --protocol {protocol} --input dbc --rate {rate} --stats {q(str(d / 'node.json'))} "
            f"--ready-file {q(str(d / 'ready'))} -l warn > {q(str(d / 'node.log'))} 2>&1 & N=$!",
            f"while [ ! -f {q(str(d / 'ready'))} ]; do sleep 0.02; done; sleep 0.3",
            f"canplayer -I {q(str(imu))} vcan0=vcan0",
            "sleep 0.3; kill -TERM $N; wait $N",
        ]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=10.0, help="seconds of IMU stream per run (default 10)")
    ap.add_argument("--rates", default="100,200,400", help="output rates, Hz (default 100,200,400)")
    ap.add_argument("--protocols", default="dbc,dronecan", help="default dbc,dronecan")
    ap.add_argument("--mode", default="auto", help="vcan backend (default auto)")
    ap.add_argument("--build", default=str(ROOT / "build" / "host"), help="host build (default build/host)")
    ap.add_argument("--json", help="write the numbers as JSON")
    args = ap.parse_args(argv)
    build = Path(args.build)
    node = build / "firmware" / "app" / "attekf-node"
    if not os.access(node, os.X_OK):
        print(f"node_load: {node} is not built (cmake --build build/host)", file=sys.stderr)
        return 1
    runs = [(f"{p}-{r}", p, int(r)) for p in args.protocols.split(",") for r in args.rates.split(",")]
    vcan = vcan_run_module()
    with tempfile.TemporaryDirectory(prefix="attekf-load-") as tmp:
        work = Path(tmp)
        script = work / "run.sh"
        n_imu = imu_log(work / "imu.log", args.duration)
        script.write_text(guest_script(node, work / "imu.log", work, runs))
        res = vcan.run(f"sh {shlex.quote(str(script))}", mode=args.mode, timeout=60 + 20 * len(runs) * args.duration)
        print(f"node_load: backend {res.mode}, {res.seconds:.0f} s", file=sys.stderr)
        rows = []
        for name, protocol, rate in runs:
            d = work / name
            st = json.loads((d / "node.json").read_text())
            c = st["counters"]
            imu = read_candump(work / "imu.log")
            if c["rx_frames"] != n_imu or c["rx_overflow"] != 0:
                print(f"node_load: {name}: the node received {c['rx_frames']} of the {n_imu} IMU frames "
                      f"(kernel drops {c['rx_overflow']})", file=sys.stderr)
            # the node's frames: the same IMU frames through the virtual backend on the host
            cpu = 0.0
            for _ in range(REPEAT):
                subprocess.run([str(node), "--replay", str(work / "imu.log"), "-o", str(d / "node_out.log"),
                                "--protocol", protocol, "--input", "dbc", "--rate", str(rate), "--stats",
                                str(d / "replay.json"), "-l", "error"], check=True, capture_output=True)
                cpu += json.loads((d / "replay.json").read_text())["cpu_s"]
            mine = read_candump(d / "node_out.log")
            span = args.duration  # per second of the IMU stream (the node is idle before and after)
            bits_mine = sum(frame_bits(i, e, d_) for _t, i, d_, e in mine)
            bits_imu = sum(frame_bits(i, e, d_) for _t, i, d_, e in imu)
            rows.append(dict(protocol=protocol, rate_hz=rate, outputs=c["outputs"], samples=c["samples"],
                             rx_overflow=c["rx_overflow"], tx_errors=c["tx_errors"], tx_frames_live=c["tx_frames"],
                             tx_frames_replay=len(mine), imu_frames=len(imu),
                             guest_cpu_pct=100.0 * st["cpu_s"] / args.duration,
                             host_replay_cpu_pct=100.0 * cpu / REPEAT / args.duration,
                             node_frames_per_s=len(mine) / span, node_kbit_s=bits_mine / span / 1e3,
                             bus_frames_per_s=(len(mine) + len(imu)) / span,
                             bus_kbit_s=(bits_mine + bits_imu) / span / 1e3))
    print(f"| protocol | output | outputs / samples | node CPU in the guest ({res.mode}) | node CPU, host replay "
          f"| node's frames/s | node's kbit/s | bus frames/s | bus kbit/s | bus at 500 kbit/s | at 1 Mbit/s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['protocol']} | {r['rate_hz']} Hz | {r['outputs']} / {r['samples']} | {r['guest_cpu_pct']:.1f} % "
              f"| {r['host_replay_cpu_pct']:.2f} % | {r['node_frames_per_s']:.0f} | {r['node_kbit_s']:.0f} "
              f"| {r['bus_frames_per_s']:.0f} | {r['bus_kbit_s']:.0f} | {r['bus_kbit_s'] / 5:.0f} % "
              f"| {r['bus_kbit_s'] / 10:.0f} % |")
    if args.json:
        Path(args.json).write_text(json.dumps(dict(backend=res.mode, duration_s=args.duration, rows=rows), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
