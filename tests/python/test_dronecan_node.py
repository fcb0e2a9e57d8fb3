"""attekf-node on DroneCAN, through its virtual backend (attekf-node --replay), spoken to and read
with the dronecan Python package (the real library): every frame the node sends must decode with
it (CRC, toggle, tail bytes), the attitude must be the DBC run's in DroneCAN's frame (converted
here independently), the services must answer as the DSDL says, and the IMU can come as RawIMU.
The same on a live bus: tests/python/hil/test_hil_dronecan.py."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import dcanutil
import prereq
from attekf import canproto as cp
from attekf.sim import SimConfig, simulate

REPO = Path(__file__).resolve().parents[2]
NODE = Path(os.environ.get("ATTEKF_NODE", REPO / "build" / "host" / "firmware" / "app" / "attekf-node"))
NODE_ID = 100
TOOL = 127
IMU = 21
RATE_HZ = 100.0


@pytest.fixture(scope="module")
def dc():
    try:
        import dronecan
    except ImportError:
        prereq.unavailable("the dronecan package is not installed "
                           "(pip install --require-hashes -r host_tools/requirements-dronecan.lock)")
    if not os.access(NODE, os.X_OK):
        pytest.fail(f"{NODE} is not built: cmake --build build/host (or set ATTEKF_NODE)", pytrace=False)
    return dronecan


def replay(log: Path, out: Path, *args, stats: Path = None):
    cmd = [str(NODE), "--replay", str(log), "-o", str(out), "-l", "error", *map(str, args)]
    if stats is not None:
        cmd += ["--stats", str(stats)]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    return json.loads(stats.read_text()) if stats is not None else None


def dbc_frames(rec):
    enc = cp.encode_samples(rec.t, rec.gyr, rec.acc, rec.mag)
    return [(float(t), int(i), bytes(d), False) for t, i, d in zip(enc.t, enc.ids, enc.data)]


@pytest.fixture(scope="module")
def runs(dc, tmp_path_factory):
    """One simulated recording through the node three ways: DBC in and out; DBC in, DroneCAN out;
    RawIMU in, DroneCAN out."""
    d = tmp_path_factory.mktemp("dronecan")
    rec = simulate(SimConfig(duration_s=12.0, rate_hz=RATE_HZ, seed=21, initial_rest_s=1.0))
    dcanutil.write_candump(d / "dbc.log", dbc_frames(rec))
    out = {"rec": rec, "dir": d}
    out["dbc_stats"] = replay(d / "dbc.log", d / "dbc.out", "--protocol", "dbc", stats=d / "dbc.json")
    out["dc_stats"] = replay(d / "dbc.log", d / "dc.out", "--protocol", "dronecan", "--input", "dbc",
                             "--node-id", NODE_ID, stats=d / "dc.json")
    dcanutil.write_candump(d / "raw.log", dcanutil.raw_imu_frames(rec.t, rec.gyr, rec.acc, rec.mag, IMU))
    out["raw_stats"] = replay(d / "raw.log", d / "raw.out", "--protocol", "dronecan", "--input", "dronecan",
                              "--node-id", NODE_ID, stats=d / "raw.json")
    dec = cp.OutputDecoder()
    for t, fid, data, ext in dcanutil.read_candump(d / "dbc.out"):
        dec.feed(t, fid, data)
    out["dbc_rows"] = dec.rows
    out["dc"] = dcanutil.decode_transfers(dcanutil.read_candump(d / "dc.out"))
    out["raw"] = dcanutil.decode_transfers(dcanutil.read_candump(d / "raw.out"))
    return out


def solutions(transfers):
    return [(t, tr.payload) for t, tr in dcanutil.by_type(transfers, "uavcan.equipment.ahrs.Solution")]


def test_every_frame_decodes_with_the_dronecan_package(runs):
    """decode_transfers is strict: a CRC, toggle, transfer id or tail error raises."""
    frames = dcanutil.read_candump(runs["dir"] / "dc.out")
    assert frames and all(ext for _t, _i, _d, ext in frames)
    assert len(solutions(runs["dc"])) > 0
    assert all(tr.source_node_id == NODE_ID for _t, tr in runs["dc"])
    # a Solution (53 bytes with its covariances) is a multi-frame transfer: 2 CRC bytes + 53 bytes
    # in 8 frames of 7, and the package checked that CRC; a NodeStatus (7 bytes) is one frame
    n_status = len(dcanutil.by_type(runs["dc"], "uavcan.protocol.NodeStatus"))
    assert len(frames) == 8 * len(solutions(runs["dc"])) + n_status


def test_solution_is_the_dbc_attitude_in_ned(runs):
    """The quaternion of every Solution equals the DBC run's attitude converted to NED/FRD here
    (dcanutil.ned_quaternion, independent of the node's code) within float16 resolution plus the
    DBC's angle quantisation; the rates within float16 and the DBC's rate LSB."""
    rows = [r for r in runs["dbc_rows"] if r.flags & 1]
    sols = solutions(runs["dc"])
    assert len(sols) == len(rows) > 800
    q_dc = np.array([list(s.orientation_xyzw) for _t, s in sols])
    q_dbc = dcanutil.ned_quaternion(np.array([r.euler for r in rows]))
    # DBC angles: LSB 1e-4 rad, each angle at most half an LSB off; dq/d(angle) has norm 1/2, so
    # a quaternion component moves by at most half the sum of the three: 0.5 * 3 * LSB / 2
    tol = dcanutil.f16_resolution(q_dbc) + 0.75 * cp.resolution("ATT_EULER", "Roll") * 1.01
    diff = np.abs(q_dc - q_dbc * np.where(np.sum(q_dc * q_dbc, 1, keepdims=True) < 0, -1, 1))
    assert np.all(diff <= tol), f"worst {diff.max():.2e} at {np.unravel_index(diff.argmax(), diff.shape)}"
    w_dc = np.array([list(s.angular_velocity) for _t, s in sols])
    w_dbc = np.array([r.rates for r in rows]) * np.array([1.0, -1.0, -1.0])
    assert np.all(np.abs(w_dc - w_dbc) <= dcanutil.f16_resolution(w_dbc) * 2 + cp.resolution("ATT_RATES", "RateP"))
    # timestamps: the sample times, as sent by the IMU (us)
    assert [s.timestamp.usec for _t, s in sols] == [int(round(runs["rec"].t[r.seq] * 1e6)) for r in rows]


def test_solution_covariance(runs):
    """The orientation covariance: symmetric, positive diagonal, the DBC's sigmas on the diagonal
    where the attitude is level (there the NED rotation axes are the Euler axes, up to sign)."""
    sols = solutions(runs["dc"])
    rows = [r for r in runs["dbc_rows"] if r.flags & 1]
    for (_t, s), r in zip(sols, rows):
        c = np.array(list(s.orientation_covariance)).reshape(3, 3)
        assert np.allclose(c, c.T, rtol=0, atol=1e-9)
        assert np.all(np.diag(c) > 0)
        assert len(s.angular_velocity_covariance) == 3 and len(s.linear_acceleration_covariance) == 0
    level = [(s, r) for (_t, s), r in zip(sols, rows) if abs(r.euler[0]) < 0.02 and abs(r.euler[1]) < 0.02]
    assert level, "no level attitude in the run"
    for s, r in level:
        c = np.array(list(s.orientation_covariance)).reshape(3, 3)
        assert np.allclose(np.sqrt(np.diag(c)), r.sigma, rtol=0.05, atol=2e-4)


def test_node_status_every_second_of_the_sample_clock(runs):
    st = [(t, tr.payload) for t, tr in dcanutil.by_type(runs["dc"], "uavcan.protocol.NodeStatus")]
    dur = runs["rec"].t[-1] - runs["rec"].t[0]
    assert abs(len(st) - (int(dur) + 1)) <= 1
    assert np.allclose(np.diff([t for t, _s in st]), 1.0, atol=0.011)
    assert [s.uptime_sec for _t, s in st] == list(range(len(st)))
    assert st[0][1].mode == 1 and st[-1][1].mode == 0             # initialisation, operational
    assert all(s.health == 0 for _t, s in st[1:])                  # a clean stream: ok
    assert st[-1][1].vendor_specific_status_code & 1               # ATT_FLAG_ALIGNED


def test_raw_imu_input_gives_the_same_attitude(runs):
    """The IMU as RawIMU + MagneticFieldStrength2 (float16, FRD, Gauss) instead of DBC frames: the
    same attitude within the difference of the two quantisations (measured: the largest
    quaternion difference over the run)."""
    a, b = solutions(runs["dc"]), solutions(runs["raw"])
    assert runs["raw_stats"]["counters"]["samples"] == len(runs["rec"])
    assert runs["raw_stats"]["counters"]["transfer_errors"] == 0
    assert runs["raw_stats"]["counters"]["gaps"] == 0
    assert abs(len(a) - len(b)) <= 1
    n = min(len(a), len(b))
    qa = np.array([list(s.orientation_xyzw) for _t, s in a[-n:]])
    qb = np.array([list(s.orientation_xyzw) for _t, s in b[-n:]])
    assert np.max(dcanutil.quat_distance(qa, qb)) < 0.01


def test_counters_of_the_dronecan_run(runs):
    c = runs["dc_stats"]["counters"]
    assert c["samples"] == len(runs["rec"]) and c["foreign"] == 0 and c["transfer_errors"] == 0
    assert runs["dc_stats"]["protocol"] == "dronecan"


# ---------------------------------------------------------------------------------------------
# Services
# ---------------------------------------------------------------------------------------------
def _requests(dc, t0: float):
    """A configuration session of a ground tool: node info, read two parameters, set them (one
    live, one at restart), an out-of-range value, save, restart with a wrong then the right magic
    number, read both again."""
    P = dc.uavcan.protocol.param
    reqs = [
        dc.uavcan.protocol.GetNodeInfo.Request(),
        P.GetSet.Request(name="mag_declination"),
        P.GetSet.Request(name="accel_lpf_order"),
        P.GetSet.Request(name="mag_declination", value=P.Value(real_value=0.125)),
        P.GetSet.Request(name="accel_lpf_order", value=P.Value(integer_value=1)),
        P.GetSet.Request(name="gyro_noise", value=P.Value(real_value=-1.0)),
        P.GetSet.Request(index=0),
        P.GetSet.Request(name="no.such.parameter"),
        P.ExecuteOpcode.Request(opcode=P.ExecuteOpcode.Request().OPCODE_SAVE),
        dc.uavcan.protocol.RestartNode.Request(magic_number=123),
        dc.uavcan.protocol.RestartNode.Request(magic_number=dcanutil.RESTART_MAGIC),
        P.GetSet.Request(name="mag_declination"),
        P.GetSet.Request(name="accel_lpf_order"),
    ]
    frames = []
    for k, r in enumerate(reqs):
        frames += dcanutil.transfer_frames(r, t0 + 0.1 * k, TOOL, k, dest=NODE_ID, priority=30)
    return reqs, frames


def _value(v):
    """A param.Value as a Python number (None if empty)."""
    from dronecan import transport
    f = transport.get_active_union_field(v)
    return None if f in (None, "empty") else getattr(v, f)


@pytest.fixture(scope="module")
def session(dc, tmp_path_factory):
    d = tmp_path_factory.mktemp("services")
    reqs, frames = _requests(dc, 1.0)
    dcanutil.write_candump(d / "in.log", frames)
    params = d / "node.params"
    stats = replay(d / "in.log", d / "out.log", "--protocol", "dronecan", "--node-id", NODE_ID,
                   "--unique-id", "00112233445566778899AABBCCDDEEFF", "--params", params, stats=d / "st.json")
    resp = [tr for _t, tr in dcanutil.decode_transfers(dcanutil.read_candump(d / "out.log"))
            if tr.service_not_message]
    assert all(r.dest_node_id == TOOL and not r.request_not_response for r in resp)
    return reqs, resp, stats, params, d


def test_services_answer_every_request(session):
    reqs, resp, stats, _p, _d = session
    assert len(resp) == len(reqs)
    assert [r.transfer_id for r in resp] == list(range(len(reqs)))
    assert stats["counters"]["requests"] == len(reqs)
    assert stats["counters"]["refused"] == 3           # out of range, no such parameter, wrong magic


def test_get_node_info(session):
    _reqs, resp, _s, _p, _d = session
    info = resp[0].payload
    assert info.name.decode() == dcanutil.NODE_NAME
    assert bytes(info.hardware_version.unique_id) == bytes.fromhex("00112233445566778899AABBCCDDEEFF")
    assert info.status.mode == 1                        # no IMU yet: initialisation
    assert (info.software_version.major, info.software_version.minor) == (0, 1)


def test_param_get_set_live_and_at_restart(session):
    _reqs, resp, _s, _p, _d = session
    decl, order = resp[1].payload, resp[2].payload
    assert decl.name.decode() == "mag_declination" and _value(decl.value) == 0.0
    assert _value(decl.min_value) == pytest.approx(-np.pi) and _value(decl.max_value) == pytest.approx(np.pi)
    assert order.name.decode() == "accel_lpf_order" and _value(order.value) == 2
    assert _value(order.default_value) == 2 and (_value(order.min_value), _value(order.max_value)) == (1, 2)
    assert _value(resp[3].payload.value) == pytest.approx(0.125)     # live: in force
    assert _value(resp[4].payload.value) == 1                        # kept for the restart
    assert _value(resp[5].payload.value) == pytest.approx(2.958e-4, rel=1e-3)  # refused: unchanged
    assert resp[6].payload.name.decode() != ""                       # by index
    assert resp[7].payload.name.decode() == "" and _value(resp[7].payload.value) is None
    assert resp[8].payload.ok                                        # saved
    assert not resp[9].payload.ok and resp[10].payload.ok            # wrong, right magic
    assert _value(resp[11].payload.value) == pytest.approx(0.125)
    assert _value(resp[12].payload.value) == 1                       # in force after the restart


def test_saved_parameters_persist(session, tmp_path):
    """ExecuteOpcode SAVE wrote the file; a node started with it has the values (and says so in
    --list-params)."""
    _reqs, _resp, _s, params, _d = session
    text = params.read_text()
    assert "mag_declination 0.125" in text and "accel_lpf_order 1" in text
    p = subprocess.run([str(NODE), "--params", str(params), "--list-params"], capture_output=True, text=True)
    assert p.returncode == 0
    line = next(l for l in p.stdout.splitlines() if " accel_lpf_order " in l)
    assert line.split()[2] == "1" and line.endswith("at restart")
    bad = tmp_path / "bad.params"
    bad.write_text("gyro_noise 0.001\nmag_declination 9\n")
    p = subprocess.run([str(NODE), "--params", str(bad), "--list-params"], capture_output=True, text=True)
    assert p.returncode == 1 and f"{bad}:2:" in p.stderr and "mag_declination" in p.stderr


def test_restart_resets_the_uptime(session):
    _reqs, _resp, _s, _p, d = session
    st = [(t, tr.payload) for t, tr in dcanutil.by_type(
        dcanutil.decode_transfers(dcanutil.read_candump(d / "out.log")), "uavcan.protocol.NodeStatus")]
    ups = [s.uptime_sec for _t, s in st]
    assert 0 in ups[1:], ups                         # back to 0 after the restart
    i = ups.index(0, 1)
    assert st[i][1].vendor_specific_status_code & 0x8000 == 0          # nothing pending any more
    assert any(s.vendor_specific_status_code & 0x8000 for _t, s in st[:i])  # pending before it
