"""The node on a DroneCAN bus, in a guest with vcan0 (the first backend of the vcan runner that
works here; docs/hil.md): a node of the dronecan Python package (the real library) and candump
see the estimator. dronecan_guest.py runs inside the guest; this file prepares its inputs, runs
the same frames through the node's virtual backend on the host, and checks.

  config   the library discovers the estimator, reads its GetNodeInfo, reads two parameters and
           sets them (one in force at once, one at the restart), saves them, restarts the node
           (a wrong magic number first) and sees it come back; then the IMU stream, whose
           ahrs.Solution the library decodes: its quaternions equal the virtual-backend run's
           within float16 resolution.
  traffic  the same stream with 5 other DroneCAN nodes' traffic on the bus (their messages and
           services, encoded by the library, played by canplayer): the node loses nothing,
           counts every one of their frames as foreign and its health stays ok."""

from __future__ import annotations

import json
import os
import shlex
import sys
from pathlib import Path

import numpy as np
import pytest

import hilutil
import prereq
from hilutil import report

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # tests/python: dcanutil
import dcanutil  # noqa: E402

GUEST = Path(__file__).resolve().parent / "dronecan_guest.py"
NODE_ID = 100
RATE_HZ = 200.0
STREAM_S = 8.0
TRAFFIC_S = 14.0
LIVE_PARAM, RESTART_PARAM = "mag_declination", "accel_lpf_order"


@pytest.fixture(scope="module")
def dc_hil(tmp_path_factory, vcan, node):
    try:
        import dronecan  # noqa: F401
    except ImportError:
        prereq.unavailable("the dronecan package is not installed "
                           "(pip install --require-hashes -r host_tools/requirements-dronecan.lock)")
    from attekf.io import write_recording_csv
    from attekf.sim import SimConfig, simulate
    root = tmp_path_factory.mktemp("hil_dronecan")
    rec = simulate(SimConfig(duration_s=STREAM_S, rate_hz=RATE_HZ, seed=31))
    write_recording_csv(str(root / "stream.csv"), rec)
    hilutil.write_log(root / "stream.log", hilutil.recording_frames(rec))
    traffic = dcanutil.other_nodes_traffic(TRAFFIC_S)
    dcanutil.write_candump(root / "traffic.log", traffic)
    py = os.environ.get("ATTEKF_PYTHON", sys.executable)
    cmd = " ".join(shlex.quote(str(a)) for a in (py, GUEST, "--node", node, "--work", root, "--stream",
                                                 root / "stream.csv", "--traffic", root / "traffic.log"))
    res = vcan.run(cmd, env=dict(os.environ), timeout=600)
    report(f"DroneCAN HIL ran on backend {res.mode}, {res.seconds:.1f} s wall time")
    result_file = root / "result.json"
    logs = "".join(f"\n--- {p}\n{p.read_text()[-1500:]}" for p in sorted(root.glob("*/*.log")) if p.stat().st_size)
    assert result_file.exists(), f"guest wrote no result (exit {res.returncode}): {res.stderr[-2000:]}{logs}"
    result = json.loads(result_file.read_text())
    for phase in ("config", "traffic"):
        assert "error" not in result[phase], f"{phase}: {result[phase]['error']}{logs}"
    # the virtual-backend run of the same frames, with the parameters the node saved
    params = root / "node.params"
    assert params.exists(), "the node did not save its parameters"
    stats = hilutil.run_virtual(root / "stream.log", root / "virtual.log", root / "virtual.json",
                                ["--protocol", "dronecan", "--input", "dbc", "--node-id", str(NODE_ID),
                                 "--params", str(params)])
    return dict(rec=rec, root=root, result=result, traffic=traffic, virtual_stats=stats,
                virtual=_solutions(dcanutil.read_candump(root / "virtual.log")))


def _solutions(frames):
    sols = dcanutil.by_type(dcanutil.decode_transfers([f for f in frames]), "uavcan.equipment.ahrs.Solution")
    return [(s.timestamp.usec, [float(v) for v in s.orientation_xyzw]) for _t, tr in sols
            for s in [tr.payload] if tr.source_node_id == NODE_ID]


def _node_stats(h, phase):
    return json.loads((h["root"] / phase / "node.json").read_text())


def test_discovers_the_node_and_reads_its_info(dc_hil):
    c = dc_hil["result"]["config"]
    assert c["monitor_info"] is not None, "the library's node monitor did not discover the estimator"
    assert c["monitor_info"]["name"] == dcanutil.NODE_NAME
    assert c["info"]["name"] == dcanutil.NODE_NAME
    assert c["info"]["unique_id"] == "0123456789abcdef0123456789abcdef"
    assert c["info"]["mode"] == 1                       # no IMU yet: initialisation
    report(f"DroneCAN: the dronecan package's node discovered the estimator in {c['discovered_s']:.1f} s "
           f"and read its GetNodeInfo ({c['info']['name']}, software {c['info']['version']})")


def test_reads_and_sets_two_parameters_and_restarts_it(dc_hil):
    c = dc_hil["result"]["config"]
    live, restart = c["read"]
    assert live["name"] == LIVE_PARAM and live["value"] == 0.0
    assert restart["name"] == RESTART_PARAM and restart["value"] == 2 and (restart["min"], restart["max"]) == (1, 2)
    assert c["set"][0]["value"] == pytest.approx(0.0625) and c["set"][1]["value"] == 1
    assert c["saved"] is True
    assert c["restart_wrong_magic"] is False and c["restart"] is True
    assert c["uptime_after_restart"] and c["uptime_after_restart"][0] == 0, c["uptime_after_restart"]
    assert c["info_after_restart"] == dcanutil.NODE_NAME
    assert c["read_after_restart"][0]["value"] == pytest.approx(0.0625)
    assert c["read_after_restart"][1]["value"] == 1
    text = (dc_hil["root"] / "node.params").read_text()
    assert "mag_declination 0.0625" in text and "accel_lpf_order 1" in text
    st = _node_stats(dc_hil, "config")["counters"]
    assert st["requests"] >= 10 and st["refused"] == 1          # the wrong magic number


def test_solution_equals_the_virtual_run(dc_hil):
    """The Solutions the library decoded on the live bus, and those candump logged, are the
    virtual-backend run's: the same samples, quaternions within float16 resolution."""
    c = dc_hil["result"]["config"]
    virt = dict(dc_hil["virtual"])
    live = [(ts, q) for _t, q, ts in c["solutions"]]
    bus = _solutions(dcanutil.read_candump(dc_hil["root"] / "config" / "bus.log"))
    assert [ts for ts, _q in bus] == [ts for ts, _q in dc_hil["virtual"]]
    # the Python client may fall behind a busy bus in an emulated guest: what it decoded must be
    # right (at a load average of 5 it kept about half); that every Solution was on the bus is
    # candump's
    assert len(live) >= len(bus) // 10, f"the client decoded {len(live)} Solutions, candump logged {len(bus)}"
    for ts, q in live + bus:
        ref = np.array(virt[ts])
        assert np.all(np.abs(np.array(q) - ref) <= dcanutil.f16_resolution(ref)), (ts, q, ref)
    same = sum(virt[ts] == q for ts, q in bus)
    st = _node_stats(dc_hil, "config")["counters"]
    assert st["samples"] == len(dc_hil["rec"]) and st["gaps"] == 0 and st["rx_overflow"] == 0
    report(f"DroneCAN: {len(bus)} ahrs.Solution on the bus ({len(live)} decoded live by the dronecan package, "
           f"{c['client_transfer_errors']} transfers it refused after losing frames of its own), "
           f"{same} bit-identical to the virtual-backend run")


def test_other_nodes_traffic_loses_nothing_and_sets_no_error(dc_hil):
    r = dc_hil["result"]["traffic"]
    assert r["replay_rc"] == 0 and r["canplayer_rc"] == 0 and r["node_rc"] == 0
    st = _node_stats(dc_hil, "traffic")["counters"]
    n_imu = len(hilutil.read_log(dc_hil["root"] / "stream.log"))
    n_other = len(dc_hil["traffic"])
    assert st["rx_overflow"] == 0
    assert st["rx_frames"] == n_imu + n_other, "frames lost between the bus and the node"
    assert st["foreign"] == n_other
    assert st["samples"] == len(dc_hil["rec"])
    for k in ("transfer_errors", "bad_dlc", "duplicate", "late", "incomplete", "discarded", "gaps", "missing",
              "time_errors", "resync", "realign", "ekf_rejected", "tx_errors", "link_down"):
        assert st[k] == 0, k
    frames = dcanutil.read_candump(dc_hil["root"] / "traffic" / "bus.log")
    transfers = dcanutil.decode_transfers(frames)
    mine = [(t, tr) for t, tr in transfers if tr.source_node_id == NODE_ID]
    bus = _solutions([f for f in frames])
    assert [ts for ts, _q in bus] == [ts for ts, _q in dc_hil["virtual"]]
    assert all(q == dict(dc_hil["virtual"])[ts] for ts, q in bus)
    status = [(t, tr.payload) for t, tr in dcanutil.by_type(mine, "uavcan.protocol.NodeStatus")]
    sol_t = [t for t, tr in dcanutil.by_type(mine, "uavcan.equipment.ahrs.Solution")]
    during = [s for t, s in status if sol_t[0] < t <= sol_t[-1]]
    assert during and all(s.health == 0 and s.mode == 0 for s in during), [(s.health, s.mode) for s in during]
    report(f"DroneCAN with 5 other nodes: {n_other} of their frames on the bus, all counted as foreign; "
           f"{n_imu} IMU frames, {st['samples']} samples, {len(bus)} Solutions, all equal to the virtual run; "
           f"health ok in all {len(during)} NodeStatus during the stream")
