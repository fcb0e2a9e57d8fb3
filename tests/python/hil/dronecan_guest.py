#!/usr/bin/env python3
"""The DroneCAN hardware-in-loop run inside a guest with vcan0 (started by test_hil_dronecan.py
through the vcan runner; everything it writes goes to WORK on the shared file system).

Phase "config": attekf-node speaks DroneCAN on vcan0, candump logs the bus, and a node of the
dronecan Python package (the real library, node id 127) does what a ground tool does: it
discovers the estimator from its NodeStatus, reads its GetNodeInfo, reads two parameters, sets
them (one in force at once, one at the next restart), saves them, restarts the node (a wrong
magic number first), sees it come back (uptime from 0), reads both parameters again. Then the
IMU stream (our DBC frames, `attekf replay` at recorded time) and the Solutions the library
decodes on the bus.

Phase "traffic": the node again (with the parameter file it saved), the IMU stream again, and
the traffic of 5 other DroneCAN nodes (frames the library encoded, played by can-utils'
canplayer at their times).

    dronecan_guest.py --node BIN --work DIR --stream REC.csv --traffic TRAFFIC.log

Writes WORK/config.json (what the client saw), WORK/{config,traffic}/ (node.json, node.log,
bus.log, replay.json). Exit status 0 if every step ran (the checks are the test's), 1 if not."""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
import traceback
from pathlib import Path

NODE_ID = 100
CLIENT_ID = 127
RESTART_MAGIC = 0xACCE551B1E
LIVE_PARAM, LIVE_VALUE = "mag_declination", 0.0625           # in force at once
RESTART_PARAM, RESTART_VALUE = "accel_lpf_order", 1          # at the next restart
RUNNING = []                                                  # processes of the current phase


def start_node(node: str, d: Path, params: Path) -> subprocess.Popen:
    ready = d / "node.ready"
    p = subprocess.Popen([node, "-i", "vcan0", "--protocol", "dronecan", "--input", "dbc", "--node-id",
                          str(NODE_ID), "--unique-id", "0123456789ABCDEF0123456789ABCDEF", "--params", str(params),
                          "--ready-file", str(ready), "--stats", str(d / "node.json")],
                         stdout=open(d / "node.log", "w"), stderr=subprocess.STDOUT)
    RUNNING.append(p)
    for _ in range(600):
        if ready.exists() or p.poll() is not None:
            break
        time.sleep(0.02)
    if not ready.exists():
        raise SystemExit(f"node did not start: {(d / 'node.log').read_text()}")
    return p


def start_candump(d: Path) -> subprocess.Popen:
    # a large receive buffer: candump shares one virtual CPU with Python processes
    p = subprocess.Popen(["candump", "-L", "-r", "8388608", "vcan0"], stdout=open(d / "bus.log", "w"),
                         stderr=subprocess.DEVNULL)
    RUNNING.append(p)
    time.sleep(0.2)
    return p


def start_replay(stream: str, d: Path) -> subprocess.Popen:
    p = subprocess.Popen([sys.executable, "-m", "attekf", "replay", "-q", stream, "-i", "socketcan", "-c", "vcan0",
                          "--stats", str(d / "replay.json")],
                         stdout=open(d / "replay.log", "w"), stderr=subprocess.STDOUT)
    RUNNING.append(p)
    return p


def stop(p: subprocess.Popen, sig=signal.SIGTERM) -> int:
    if p.poll() is None:
        p.send_signal(sig)
    return p.wait(timeout=30)


class Client:
    """A dronecan node that asks, and remembers what it saw of the estimator."""

    def __init__(self):
        import dronecan
        from dronecan.app.node_monitor import NodeMonitor
        from dronecan.driver.socketcan import SocketCAN
        self.dc = dronecan
        # the package's own SocketCAN driver (its python-can driver calls a python-can method the
        # socketcan interface does not implement when a write times out), with a receive buffer
        # that holds a few seconds of the bus while Python falls behind in an emulated guest
        import socket as so
        drv = SocketCAN("vcan0")
        drv.socket.setsockopt(so.SOL_SOCKET, 33, 8 << 20)      # SO_RCVBUFFORCE (root in the guest)
        self.node = dronecan.node.Node(drv, node_id=CLIENT_ID)
        self.transfer_errors = 0   # transfers the package refused (frames this client lost)
        self.monitor = NodeMonitor(self.node)
        self.status = []            # (time, uptime, health, mode, vendor code)
        self.solutions = []         # (time, [x, y, z, w], timestamp usec)
        self.node.add_handler(dronecan.uavcan.protocol.NodeStatus, self._on_status)
        self.node.add_handler(dronecan.uavcan.equipment.ahrs.Solution, self._on_solution)

    def _on_status(self, e):
        if e.transfer.source_node_id == NODE_ID:
            m = e.message
            self.status.append((time.monotonic(), m.uptime_sec, m.health, m.mode, m.vendor_specific_status_code))

    def _on_solution(self, e):
        if e.transfer.source_node_id == NODE_ID:
            m = e.message
            self.solutions.append((time.monotonic(), [float(v) for v in m.orientation_xyzw], int(m.timestamp.usec)))

    def spin(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self._spin(min(0.05, max(0.0, end - time.monotonic())))

    def _spin(self, timeout: float) -> None:
        try:
            self.node.spin(timeout)
        except self.dc.transport.TransferError:
            self.transfer_errors += 1

    def call(self, request, timeout: float = 3.0):
        box = {}
        self.node.request(request, NODE_ID, lambda e: box.setdefault("e", e), timeout=timeout)
        end = time.monotonic() + timeout + 1.0
        while "e" not in box and time.monotonic() < end:
            self._spin(0.05)
        e = box.get("e")
        return None if e is None else e.response

    def get_set(self, name, value=None):
        P = self.dc.uavcan.protocol.param
        req = P.GetSet.Request(name=name) if value is None else P.GetSet.Request(name=name, value=value)
        r = self.call(req)
        return None if r is None else {"name": r.name.decode(), "value": _value(r.value),
                                       "default": _value(r.default_value), "min": _value(r.min_value),
                                       "max": _value(r.max_value)}


def _value(v):
    from dronecan import transport
    f = transport.get_active_union_field(v)
    return None if f in (None, "empty") else getattr(v, f)


def config_phase(args, d: Path, params: Path) -> dict:
    out = {}
    candump = start_candump(d)
    node = start_node(args.node, d, params)
    c = Client()
    t0 = time.monotonic()
    while time.monotonic() - t0 < 15:                 # discovery: its NodeStatus, then GetNodeInfo
        c.spin(0.2)
        if c.monitor.exists(NODE_ID) and c.monitor.get(NODE_ID).info is not None:
            break
    entry = c.monitor.get(NODE_ID) if c.monitor.exists(NODE_ID) else None
    out["discovered_s"] = time.monotonic() - t0
    out["monitor_info"] = None if entry is None or entry.info is None else {
        "name": entry.info.name.decode(), "unique_id": bytes(entry.info.hardware_version.unique_id).hex()}
    info = c.call(c.dc.uavcan.protocol.GetNodeInfo.Request())
    out["info"] = None if info is None else {
        "name": info.name.decode(), "unique_id": bytes(info.hardware_version.unique_id).hex(),
        "mode": info.status.mode, "version": [info.software_version.major, info.software_version.minor]}
    P = c.dc.uavcan.protocol.param
    out["read"] = [c.get_set(LIVE_PARAM), c.get_set(RESTART_PARAM)]
    out["set"] = [c.get_set(LIVE_PARAM, P.Value(real_value=LIVE_VALUE)),
                  c.get_set(RESTART_PARAM, P.Value(integer_value=RESTART_VALUE))]
    r = c.call(P.ExecuteOpcode.Request(opcode=P.ExecuteOpcode.Request().OPCODE_SAVE))
    out["saved"] = None if r is None else bool(r.ok)
    r = c.call(c.dc.uavcan.protocol.RestartNode.Request(magic_number=1234))
    out["restart_wrong_magic"] = None if r is None else bool(r.ok)
    n_before = len(c.status)
    r = c.call(c.dc.uavcan.protocol.RestartNode.Request(magic_number=RESTART_MAGIC))
    out["restart"] = None if r is None else bool(r.ok)
    c.spin(2.5)                                        # it comes back: NodeStatus from uptime 0
    out["uptime_after_restart"] = [s[1] for s in c.status[n_before:]]
    info = c.call(c.dc.uavcan.protocol.GetNodeInfo.Request())
    out["info_after_restart"] = None if info is None else info.name.decode()
    out["read_after_restart"] = [c.get_set(LIVE_PARAM), c.get_set(RESTART_PARAM)]
    # the IMU stream; the client decodes the Solutions as they come
    n_sol, n_stat = len(c.solutions), len(c.status)
    replay = start_replay(args.stream, d)
    while replay.poll() is None:
        c.spin(0.1)
    c.spin(0.6)
    out["replay_rc"] = replay.returncode
    out["solutions"] = c.solutions[n_sol:]
    out["client_transfer_errors"] = c.transfer_errors
    out["status_during_stream"] = c.status[n_stat:]
    out["node_rc"] = stop(node)
    out["candump_rc"] = stop(candump, signal.SIGINT)
    c.node.close()
    return out


def traffic_phase(args, d: Path, params: Path) -> dict:
    candump = start_candump(d)
    node = start_node(args.node, d, params)
    player = subprocess.Popen(["canplayer", "-I", args.traffic, "vcan0=vcan0"], stdout=subprocess.DEVNULL,
                              stderr=open(d / "canplayer.log", "w"))
    RUNNING.append(player)
    time.sleep(0.5)                                     # the other nodes are talking already
    replay = start_replay(args.stream, d)
    replay.wait(timeout=120)
    out = {"replay_rc": replay.returncode, "canplayer_rc": player.wait(timeout=120)}
    time.sleep(0.5)
    out["node_rc"] = stop(node)
    out["candump_rc"] = stop(candump, signal.SIGINT)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--node", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--stream", required=True, help="recording CSV replayed as the IMU's DBC frames")
    ap.add_argument("--traffic", required=True, help="candump log of the other nodes' frames")
    args = ap.parse_args()
    work = Path(args.work)
    params = work / "node.params"
    result = {}
    for name, phase in (("config", config_phase), ("traffic", traffic_phase)):
        d = work / name
        d.mkdir(parents=True, exist_ok=True)
        try:
            result[name] = phase(args, d, params)
        except Exception as e:                         # the test reports it with the logs
            result[name] = {"error": f"{type(e).__name__}: {e}\n{traceback.format_exc()}"}
        finally:
            for p in RUNNING:                          # nothing of a phase outlives it
                if p.poll() is None:
                    p.kill()
                    p.wait()
            RUNNING.clear()
    (work / "result.json").write_text(json.dumps(result, indent=1))
    return 0 if all("error" not in r for r in result.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
