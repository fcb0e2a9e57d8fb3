"""Helpers of the hardware-in-loop tests: the node binary, the UML/vcan runner, virtual-backend
runs, frame logs with injected faults, decoding of logs."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, List, Tuple

import numpy as np

REPO = Path(__file__).resolve().parents[3]
SCENARIO = REPO / "hal" / "tools" / "hil_scenario.sh"
REPORT: List[str] = []   # lines for the terminal summary (measured loss, latency)
FULL_SUITE_BACKEND: List[str] = []   # the backend the full HIL suite ran on in this session


def report(line: str) -> None:
    REPORT.append(line)


def node_binary() -> Path:
    return Path(os.environ.get("ATTEKF_NODE", REPO / "build" / "host" / "firmware" / "app" / "attekf-node"))


def vcan_run_module():
    """hal/tools/vcan_run.py, imported by path (it is a stand-alone script; its backend
    modules beside it become importable as vcan_guest, vcan_uml, vcan_qemu). Imported once:
    the runner remembers which backends failed in this process."""
    if "vcan_run" in sys.modules:
        return sys.modules["vcan_run"]
    spec = importlib.util.spec_from_file_location("vcan_run", REPO / "hal" / "tools" / "vcan_run.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["vcan_run"] = mod
    spec.loader.exec_module(mod)
    return mod


def read_ifstats(path: Path) -> Dict[str, Dict[str, int]]:
    """hil_scenario.sh's ifstats.txt: {"start": {"rx_dropped": N, ...}, "end": {...}}."""
    out: Dict[str, Dict[str, int]] = {}
    for line in path.read_text().splitlines():
        label, *pairs = line.split()
        out[label] = {k: int(v) for k, v in (p.split("=", 1) for p in pairs) if v.lstrip("-").isdigit()}
    return out


# ---------------------------------------------------------------------------------------------
# Frames
# ---------------------------------------------------------------------------------------------
Frame = Tuple[float, int, bytes, bool]   # (time s, id, payload, extended id)


def recording_frames(rec) -> List[Frame]:
    """The input frames of a Recording, as `attekf replay` sends them."""
    from attekf import canproto
    enc = canproto.encode_samples(rec.t, rec.gyr, rec.acc, rec.mag)
    return [(float(t), int(i), bytes(d), False) for t, i, d in zip(enc.t, enc.ids, enc.data)]


def write_log(path: Path, frames: List[Frame]) -> None:
    import can
    with can.Logger(str(path)) as log:
        for t, fid, data, ext in frames:
            log(can.Message(timestamp=t, arbitration_id=fid, data=data, is_extended_id=ext,
                            is_rx=False, channel="vcan0"))


def write_candump(path: Path, frames: List[Frame]) -> None:
    """candump -L format without python-can's direction suffix (what canplayer reads)."""
    with open(path, "w") as fh:
        for t, fid, data, ext in frames:
            fh.write(f"({t:.6f}) vcan0 {fid:08X}#{data.hex().upper()}\n" if ext
                     else f"({t:.6f}) vcan0 {fid:03X}#{data.hex().upper()}\n")


def read_log(path: Path) -> List[Frame]:
    import can
    return [(float(m.timestamp), int(m.arbitration_id), bytes(m.data), bool(m.is_extended_id))
            for m in can.LogReader(str(path)) if not (m.is_error_frame or m.is_remote_frame)]


@dataclass
class FaultPlan:
    frames: List[Frame]
    expected: Dict[str, int]      # node counters the faults must produce (virtual run: exactly)
    fault_samples: List[int]      # samples touched


def inject_faults(frames: List[Frame], n_samples: int, late_part: int) -> FaultPlan:
    """Applies the protocol's fault classes to a clean frame list (4 frames per sample, in the
    order gyro, accel, mag, sync). Faults sit at samples 100..450 and late_part..late_part+50,
    so a bus bounce between them does not touch them. Returns the frames and the counters the
    node must report for them (docs/can_protocol.md, "Node behaviour")."""
    from attekf import canproto
    gid, aid, mid, sid = (canproto.frame_id(n) for n in canproto.INPUT_MESSAGES)
    per = {}
    for f in frames:
        seq = int.from_bytes(f[2][6:8] if f[1] != sid else f[2][4:6], "little")
        per.setdefault(seq, []).append(f)
    assert len(per) == n_samples and all(len(v) == 4 for v in per.values())

    def kind(frs, fid):
        return next(f for f in frs if f[1] == fid)

    out: List[Frame] = []
    moved: Dict[int, List[Frame]] = {}
    exp = dict(foreign=0, bad_dlc=0, duplicate=0, late=0, incomplete=0, discarded=0, gaps=0,
               missing=0)
    L = late_part
    for k in range(n_samples):
        frs = list(per[k])
        if k == 100:                       # lost gyro frame: sample without gyro
            frs.remove(kind(frs, gid))
            exp["incomplete"] += 1
        elif 150 <= k <= 152:              # three samples lost entirely
            frs = []
            if k == 150:
                exp["gaps"] += 1
            exp["missing"] += 1
        elif k == 200:                     # accelerometer frame duplicated at once
            a = kind(frs, aid)
            frs.insert(frs.index(a) + 1, a)
            exp["duplicate"] += 1
        elif k == 210:                     # the whole sample sent twice
            frs = frs + frs
            exp["duplicate"] += 4
        elif k == 250:                     # IMU_SYNC of 250 after IMU_GYRO of 251 (priority order)
            sync = kind(frs, sid)
            frs.remove(sync)
            nxt = list(per[251])
            g = kind(nxt, gid)
            frs += [g, sync]
            per[251] = [f for f in nxt if f is not g]
        elif k == 300:                     # mag frame of 300 arrives after sample 302
            m = kind(frs, mid)
            frs.remove(m)
            moved.setdefault(302, []).append(m)
            exp["incomplete"] += 1
            exp["late"] += 1
        elif k == 350:                     # gyro frame truncated to 6 bytes
            g = kind(frs, gid)
            frs[frs.index(g)] = (g[0], g[1], g[2][:6], g[3])
            exp["bad_dlc"] += 1
            exp["incomplete"] += 1
        elif k == 360:                     # stray 4-byte frame with the IMU_SYNC id
            frs.insert(0, (frs[0][0], sid, b"\x01\x02\x03\x04", False))
            exp["bad_dlc"] += 1
        elif k == 400:                     # foreign traffic: two 11-bit ids, one 29-bit
            t = frs[0][0]
            frs[0:0] = [(t, 0x555, b"\x00" * 8, False), (t, 0x7FF, b"\x11" * 3, False),
                        (t, gid, b"\x22" * 8, True)]
            exp["foreign"] += 3
        elif k == 450:                     # IMU_SYNC lost: sample discarded (no time)
            frs.remove(kind(frs, sid))
            exp["discarded"] += 1
            exp["gaps"] += 1
            exp["missing"] += 1
        elif k == L:                       # late part: a duplicate and a foreign frame
            g = kind(frs, gid)
            frs.insert(frs.index(g) + 1, g)
            frs.insert(0, (frs[0][0], 0x321, b"\x00" * 8, False))
            exp["duplicate"] += 1
            exp["foreign"] += 1
        out.extend(frs)
        out.extend(moved.pop(k, []))
    # A moved frame goes out when its new neighbours do: keep the time stamps monotonic.
    t_prev = 0.0
    for i, (t, fid, data, ext) in enumerate(out):
        t_prev = max(t_prev, t)
        out[i] = (t_prev, fid, data, ext)
    return FaultPlan(frames=out, expected=exp,
                     fault_samples=[100, 150, 151, 152, 200, 210, 250, 251, 300, 350, 360, 400, 450, L])


# ---------------------------------------------------------------------------------------------
# Runs
# ---------------------------------------------------------------------------------------------
def run_virtual(log: Path, out_log: Path, stats: Path, extra: List[str] = ()) -> Dict:
    """attekf-node --replay: the virtual-backend run of a frame log."""
    p = subprocess.run([str(node_binary()), "--replay", str(log), "-o", str(out_log), "--stats", str(stats),
                        "-l", "error", *extra], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, f"virtual run failed: {p.stderr}"
    return json.loads(stats.read_text())


def decode_outputs(log: Path):
    from attekf import canproto
    dec = canproto.OutputDecoder()
    for t, fid, data, ext in read_log(log):
        if not ext:
            dec.feed(t, fid, data)
    return dec
