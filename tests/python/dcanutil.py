"""DroneCAN on the test side, with the dronecan Python package (the real library, not the node's
code): transfers to frames and back (the package checks CRC, toggle and tail bytes), candump
logs, and an independent conversion of the filter's attitude to DroneCAN's frame.

Frames are (time s, 29-bit id, payload bytes, extended) like hilutil.Frame."""

from __future__ import annotations

import math
from typing import Iterable, List, Optional, Sequence, Tuple

import numpy as np

Frame = Tuple[float, int, bytes, bool]
NODE_NAME = "org.attekf.ahrs"
RESTART_MAGIC = 0xACCE551B1E


def dronecan():
    import dronecan as d
    return d


def transfer_frames(payload, t: float, source: int, tid: int, dest: Optional[int] = None,
                    priority: int = 16, request: bool = True) -> List[Frame]:
    """The frames of one transfer: a message (dest None) or a service request/response."""
    from dronecan import transport
    service = dest is not None
    tr = transport.Transfer(transfer_id=tid & 31, source_node_id=source, dest_node_id=dest,
                            payload=payload, transfer_priority=priority,
                            request_not_response=request, service_not_message=service)
    return [(t, int(f.message_id), bytes(f.bytes), True) for f in tr.to_frames()]


def decode_transfers(frames: Iterable[Frame], strict: bool = True):
    """Reassembles the extended frames with the package's TransferManager and decodes each
    transfer (Transfer.from_frames raises on a CRC, toggle or tail error: strict re-raises,
    else such transfers are counted in .errors). Returns a list of (time of the first frame,
    transfer) and sets .errors on the list."""
    from dronecan import transport

    class Result(list):
        errors = 0

    mgr = transport.TransferManager()
    out = Result()
    for t, fid, data, ext in frames:
        if not ext:
            continue
        fr = transport.Frame(fid, data, ts_monotonic=t, ts_real=t)
        done = mgr.receive_frame(fr)
        if done is None:
            continue
        tr = transport.Transfer()
        try:
            tr.from_frames(done)
        except Exception:
            if strict:
                raise
            out.errors += 1
            continue
        out.append((done[0].ts_monotonic, tr))
    return out


def by_type(transfers, full_name: str, kind: str = "message"):
    """The transfers of one data type: kind "message", "request" or "response"."""
    out = []
    for t, tr in transfers:
        name = tr.payload._type.full_name
        if name != full_name:
            continue
        if kind == "message" and tr.service_not_message:
            continue
        if kind == "request" and not (tr.service_not_message and tr.request_not_response):
            continue
        if kind == "response" and not (tr.service_not_message and not tr.request_not_response):
            continue
        out.append((t, tr))
    return out


def ned_quaternion(euler_enu: np.ndarray) -> np.ndarray:
    """The filter's ZYX Euler angles (roll, pitch, yaw; body FLU to ENU, R = Rz(psi) Ry(theta)
    Rx(phi)) -> DroneCAN's orientation, (N, 4) as x, y, z, w with w >= 0, body FRD to NED.

    Independent of the node's code: the NED angles are roll, -pitch, pi/2 - yaw (a y axis that
    points left turns the pitch's sign; the heading counts from north, clockwise), then the
    aerospace quaternion of ZYX angles."""
    e = np.atleast_2d(np.asarray(euler_enu, dtype=float))
    roll, pitch, yaw = e[:, 0], -e[:, 1], math.pi / 2 - e[:, 2]
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    w = cr * cp * cy + sr * sp * sy
    x = sr * cp * cy - cr * sp * sy
    y = cr * sp * cy + sr * cp * sy
    z = cr * cp * sy - sr * sp * cy
    q = np.stack([x, y, z, w], axis=1)
    return q * np.where(q[:, 3:4] < 0, -1.0, 1.0)


def quat_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Largest component difference of unit quaternions, the sign ambiguity removed."""
    a, b = np.atleast_2d(a), np.atleast_2d(b)
    s = np.where(np.sum(a * b, axis=1, keepdims=True) < 0, -1.0, 1.0)
    return np.max(np.abs(a - s * b), axis=1)


def f16_resolution(q: np.ndarray) -> np.ndarray:
    """Half a float16 step at each value (the rounding error of storing it as float16), for
    values of magnitude up to 1: 2^-11 times the power of two at or below |v| (2^-25 below the
    normal range)."""
    a = np.abs(np.asarray(q, dtype=float))
    e = np.floor(np.log2(np.maximum(a, 2.0 ** -14)))
    return 2.0 ** (e - 11)


def raw_imu_frames(t: Sequence[float], gyr: np.ndarray, acc: np.ndarray, mag: Optional[np.ndarray],
                   source: int, t0_us: int = 1000000) -> List[Frame]:
    """A recording as an IMU on a DroneCAN bus sends it: per sample a MagneticFieldStrength2 (if
    the row has one; Gauss) then a RawIMU (timestamp t0_us + t in us; 0 would mean "unknown"),
    both in the body frame FRD (the recording's body frame is the filter's, z up: y and z change
    sign)."""
    d = dronecan()
    frames: List[Frame] = []
    flip = np.array([1.0, -1.0, -1.0])
    for k in range(len(t)):
        tk = float(t[k])
        if mag is not None and np.all(np.isfinite(mag[k])):
            m = d.uavcan.equipment.ahrs.MagneticFieldStrength2(
                sensor_id=0, magnetic_field_ga=[float(v) for v in mag[k] * flip / 100.0])
            frames += transfer_frames(m, tk, source, k)
        r = d.uavcan.equipment.ahrs.RawIMU(
            timestamp=d.TYPENAMES["uavcan.Timestamp"](usec=t0_us + int(round(tk * 1e6))),
            integration_interval=0.0,
            rate_gyro_latest=[float(v) for v in gyr[k] * flip],
            accelerometer_latest=[float(v) for v in acc[k] * flip])
        frames += transfer_frames(r, tk, source, k)
    return frames


def write_candump(path, frames: Iterable[Frame], channel: str = "vcan0") -> None:
    """candump -L lines (what attekf-node --replay and canplayer read), frames sorted by time
    (stable: the order of equal times kept)."""
    rows = sorted(frames, key=lambda f: f[0])
    with open(path, "w") as fh:
        for t, fid, data, ext in rows:
            ident = f"{fid:08X}" if ext else f"{fid:03X}"
            fh.write(f"({t:.6f}) {channel} {ident}#{data.hex().upper()}\n")


def read_candump(path) -> List[Frame]:
    out: List[Frame] = []
    for line in open(path):
        parts = line.split()
        if len(parts) < 3 or not parts[0].startswith("("):
            continue
        ident, data = parts[2].split("#", 1)
        out.append((float(parts[0][1:-1]), int(ident, 16), bytes.fromhex(data), len(ident) > 3))
    return out


def other_nodes_traffic(duration_s: float, ids: Sequence[int] = (10, 11, 12, 13, 14),
                        exclude: int = 100) -> List[Frame]:
    """What 5 other DroneCAN nodes put on a bus in duration_s, encoded by the dronecan package:
    every node's NodeStatus at 1 Hz; an ESC's status at 100 Hz (3 frames); a GNSS receiver's Fix2
    at 10 Hz (8 frames); another IMU's RawIMU at 200 Hz (7 frames) and a magnetometer at 50 Hz; a
    barometer at 20 Hz; one node asking another for its node info and a parameter at 2 Hz, and
    the answers (the same service types the estimator serves, addressed to someone else)."""
    d = dronecan()
    T = d.TYPENAMES
    a, b, c, e, f = ids
    assert exclude not in ids
    frames: List[Frame] = []
    tid = {}

    def put(msg, t, src, dest=None, request=True):
        key = (type(msg).__name__, msg._type.full_name, src, dest, request)
        k = tid.get(key, 0)
        tid[key] = k + 1
        frames.extend(transfer_frames(msg, t, src, k, dest=dest, priority=20, request=request))

    n = int(duration_s * 200)
    for i in range(n):
        t = i / 200.0
        if i % 200 == 0:
            for src in ids:
                put(T["uavcan.protocol.NodeStatus"](uptime_sec=i // 200, health=0, mode=0), t + 0.001 * src, src)
        if i % 2 == 0:
            put(T["uavcan.equipment.esc.Status"](error_count=0, voltage=16.0, current=3.5, temperature=300.0,
                                                 rpm=4000 + i, power_rating_pct=40, esc_index=0), t, a)
        if i % 20 == 0:
            put(T["uavcan.equipment.gnss.Fix2"](latitude_deg_1e8=4700000000 + i, longitude_deg_1e8=800000000,
                                                height_msl_mm=400000, sats_used=12, status=3), t, b)
        put(T["uavcan.equipment.ahrs.RawIMU"](rate_gyro_latest=[0.01, 0.0, -0.02],
                                              accelerometer_latest=[0.1, 0.0, -9.8]), t, c)
        if i % 4 == 0:
            put(T["uavcan.equipment.ahrs.MagneticFieldStrength2"](magnetic_field_ga=[0.2, 0.0, 0.4]), t, e)
        if i % 10 == 0:
            put(T["uavcan.equipment.air_data.StaticPressure"](static_pressure=95000.0 + i,
                                                              static_pressure_variance=1.0), t, f)
        if i % 100 == 0:
            put(d.uavcan.protocol.GetNodeInfo.Request(), t, e, dest=f)
            put(d.uavcan.protocol.GetNodeInfo.Response(name="org.example.baro"), t + 0.002, f, dest=e, request=False)
            put(d.uavcan.protocol.param.GetSet.Request(name="BARO_RATE"), t + 0.004, e, dest=f)
            put(d.uavcan.protocol.param.GetSet.Response(name="BARO_RATE"), t + 0.006, f, dest=e, request=False)
    return frames
