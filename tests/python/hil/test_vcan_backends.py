"""A short vcan round trip on every backend of hal/tools/vcan_run.py this machine can run, so
that a fallback cannot rot unnoticed while the full HIL suite (test_hil_vcan.py) runs on the
preferred one (docs/hil.md, "Backends").

In one guest boot: candump logs the bus (with a 4 MiB socket buffer: under emulation it reads
slower than the bus fills), attekf-node runs on vcan0, a python-can receiver
sends one frame of its own and counts the node's outputs, can-utils' canplayer sends 1 s of a
simulated IMU stream (200 samples, 800 frames). Checked: the node assembled every sample and
answered with every scheduled output, python-can received them and the node received
python-can's frame (as an unknown id), candump saw all of it.

A backend that cannot be used here is skipped with the reason, except under CI (CI=true) when
it is one the set-up provides (user-mode Linux, QEMU/TCG) or the machine offers (KVM with
vmx/svm, a kernel with CAN): then the test fails. The backend the full suite ran on in this
session is not run again."""

from __future__ import annotations

import json
import os
import shlex
import sys

import pytest

import hilutil
import prereq

PY_ID = 0x7AB
PY_DATA = b"pycan"
OUT_PERIOD_US = 10000
# The receiver asks the kernel for the node's ATT_EULER frames and its own id only (a python
# loop under emulation is slower than the bus), and stops when the shell says the replay is
# over and the bus is quiet.
RX_SCRIPT = r'''
import json, os, sys, time
import can
d, euler_id = sys.argv[1], int(sys.argv[2])
filters = [{"can_id": euler_id, "can_mask": 0x7FF, "extended": False},
           {"can_id": %d, "can_mask": 0x7FF, "extended": False}]
rx = can.Bus(interface="socketcan", channel="vcan0", can_filters=filters)
tx = can.Bus(interface="socketcan", channel="vcan0")
open(os.path.join(d, "rx.ready"), "w").close()
deadline = time.monotonic() + 300
while not os.path.exists(os.path.join(d, "node.ready")) and time.monotonic() < deadline:
    time.sleep(0.02)
tx.send(can.Message(arbitration_id=%d, data=%r, is_extended_id=False))
own = euler = 0
while time.monotonic() < deadline:
    m = rx.recv(timeout=0.5)
    if m is None:
        if os.path.exists(os.path.join(d, "stop")):
            break
        continue
    if m.arbitration_id == %d and bytes(m.data) == %r:
        own += 1
    elif m.arbitration_id == euler_id and not m.is_extended_id:
        euler += 1
json.dump({"own": own, "euler": euler}, open(os.path.join(d, "rx.json"), "w"))
''' % (PY_ID, PY_ID, PY_DATA, PY_ID, PY_DATA)


def _round_trip_script(d, node, py, euler_id):
    q = lambda p: shlex.quote(str(p))
    return (
        f"D={q(d)}; candump -r 4194304 -L vcan0 > \"$D/candump.log\" 2>&1 & CD=$!; "
        f"{q(node)} -i vcan0 --ready-file \"$D/node.ready\" --stats \"$D/node.json\" > \"$D/node.log\" 2>&1 & N=$!; "
        f"{q(py)} \"$D/rx.py\" \"$D\" {euler_id} > \"$D/rx.log\" 2>&1 & R=$!; "
        "i=0; while [ ! -f \"$D/node.ready\" ] || [ ! -f \"$D/rx.ready\" ]; do sleep 0.05; i=$((i+1)); "
        "[ $i -gt 6000 ] && break; done; "
        "canplayer -I \"$D/frames.log\" vcan0=vcan0; sleep 0.5; touch \"$D/stop\"; "
        "wait $R; echo $? > \"$D/rx.rc\"; kill -TERM $N; wait $N; echo $? > \"$D/node.rc\"; "
        "sleep 0.2; kill -INT $CD; wait $CD; true")


@pytest.mark.parametrize("backend", ["host", "uml", "qemu-kvm", "qemu-tcg"])
def test_round_trip(backend, vcan, node, tmp_path):
    from attekf import canproto
    from attekf.sim import SimConfig, simulate
    if backend in hilutil.FULL_SUITE_BACKEND:
        pytest.skip(f"{backend} ran the full HIL suite in this session")
    why, expected = vcan.backend_status()[backend]
    if why:
        if expected and prereq.in_ci():
            pytest.fail(f"{backend} should work on this machine but cannot be used: {why}", pytrace=False)
        pytest.skip(f"{backend} not usable here: {why}")
    rec = simulate(SimConfig(duration_s=1.0, rate_hz=200.0, seed=21, initial_rest_s=0.5))
    frames = hilutil.recording_frames(rec)
    hilutil.write_candump(tmp_path / "frames.log", frames)
    (tmp_path / "rx.py").write_text(RX_SCRIPT)
    euler_id = canproto.frame_id("ATT_EULER")
    n_out = int(canproto.output_schedule(canproto.time_us(rec.t), OUT_PERIOD_US).size)
    py = os.environ.get("ATTEKF_PYTHON", sys.executable)
    try:
        res = vcan.run(_round_trip_script(tmp_path, node, py, euler_id), mode=backend, timeout=600)
    except vcan.VcanError as e:
        pytest.fail(f"{backend}: {e}", pytrace=False)
    logs = "".join(f"\n--- {f}:\n" + (tmp_path / f).read_text()[-1500:]
                   for f in ("node.log", "rx.log") if (tmp_path / f).exists())
    assert res.mode == backend
    assert (tmp_path / "node.rc").read_text().strip() == "0", logs
    assert (tmp_path / "rx.rc").read_text().strip() == "0", logs
    c = json.loads((tmp_path / "node.json").read_text())["counters"]
    rx = json.loads((tmp_path / "rx.json").read_text())
    assert c["rx_frames"] == len(frames) + 1 and c["foreign"] == 1, (c, logs)
    assert c["samples"] == len(rec) and c["outputs"] == n_out, (c, logs)
    assert rx == {"own": 1, "euler": n_out}, (rx, logs)
    dump = hilutil.read_log(tmp_path / "candump.log")
    inputs = {canproto.frame_id(n) for n in canproto.INPUT_MESSAGES}
    assert sum(1 for f in dump if f[1] in inputs and not f[3]) == len(frames)
    assert any(f[1] == PY_ID and f[2] == PY_DATA for f in dump)
    assert sum(1 for f in dump if f[1] == euler_id and not f[3]) == n_out
    hilutil.report(f"round trip on {backend}: {len(frames)} frames in, {n_out} outputs out, all seen by "
                   f"python-can and candump; command started after {res.boot_seconds:.1f} s, "
                   f"{res.seconds:.1f} s in all")
