"""`attekf replay` and `attekf record` (host_tools/attekf/commands/{replay,record}.py), on
python-can's in-process `virtual` interface and on log files."""

from __future__ import annotations

import json
import threading
import time

import numpy as np
import pytest

from attekf import canproto as cp
from attekf.cli import main as attekf
from attekf.commands import record, replay
from attekf.io import read_output_csv, read_recording, write_recording_csv
from attekf.sim import SimConfig, simulate


@pytest.fixture(scope="module")
def rec_csv(tmp_path_factory):
    d = tmp_path_factory.mktemp("rr")
    rec = simulate(SimConfig(duration_s=3.0, rate_hz=100.0, seed=5, initial_rest_s=1.0))
    path = d / "rec.csv"
    write_recording_csv(str(path), rec)
    return path


def _frames(path):
    import can
    return [m for m in can.LogReader(str(path))]


def test_round_trip_through_virtual_bus(rec_csv, tmp_path):
    """sim -> CSV -> replay on python-can's virtual interface -> record -> decoded samples equal
    the original to the DBC's resolution."""
    import can
    rx = can.Bus(interface="virtual", channel="rt")
    tx = can.Bus(interface="virtual", channel="rt")
    r = record.Recorder()
    stop = [False]
    t = threading.Thread(target=record.record_bus, args=(r, rx, None, 0.0, 0.0, 0, stop, True))
    t.start()
    try:
        fr = replay.load_frames(str(rec_csv))
        st = replay.send_stream(tx, replay.iterate_loops(fr, 1, True), len(fr), fast=True, quiet=True)
        deadline = time.monotonic() + 10
        while r.frames < len(fr) and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        stop[0] = True
        t.join()
        rx.shutdown()
        tx.shutdown()
    assert st.frames == len(fr) and st.failed == 0
    out = tmp_path / "back.csv"
    assert r.write_inputs_csv(str(out)) == 0
    orig, back = read_recording(str(rec_csv)), read_recording(str(out))
    assert len(back) == len(orig)
    np.testing.assert_allclose(back.t, orig.t, atol=0.5e-6)
    np.testing.assert_allclose(back.gyr, orig.gyr, atol=cp.resolution("IMU_GYRO", "GyroX") / 2 + 1e-9)
    np.testing.assert_allclose(back.acc, orig.acc, atol=cp.resolution("IMU_ACCEL", "AccelX") / 2 + 1e-9)
    np.testing.assert_allclose(back.mag, orig.mag, atol=cp.resolution("IMU_MAG", "MagX") / 2 + 1e-9)


def test_to_log_and_log_formats_replay_identically(rec_csv, tmp_path):
    import can
    assert attekf(["replay", "-q", str(rec_csv), "--to-log", str(tmp_path / "a.log")]) == 0
    base = _frames(tmp_path / "a.log")
    rec = read_recording(str(rec_csv))
    assert len(base) == 4 * len(rec)
    assert base[0].timestamp == 0.0 and base[-1].timestamp == pytest.approx(rec.t[-1])
    # the same frames written as .asc and .blf replay to the same frames and times
    for ext in ("asc", "blf"):
        with can.Logger(str(tmp_path / f"b.{ext}")) as lg:
            for m in base:
                lg(m)
        assert attekf(["replay", "-q", str(tmp_path / f"b.{ext}"), "--to-log", str(tmp_path / f"c{ext}.log")]) == 0
        again = _frames(tmp_path / f"c{ext}.log")
        assert [(m.arbitration_id, bytes(m.data)) for m in again] == [(m.arbitration_id, bytes(m.data)) for m in base]
        np.testing.assert_allclose([m.timestamp - again[0].timestamp for m in again],
                                   [m.timestamp for m in base], atol=2e-6)


def test_start_stop_and_loop_continue_seq_and_time(rec_csv, tmp_path):
    out = tmp_path / "w.log"
    assert attekf(["replay", "-q", str(rec_csv), "--start", "1.0", "--stop", "1.5", "--loop", "2",
                   "--to-log", str(out)]) == 0
    dec = cp.InputDecoder()
    for m in _frames(out):
        dec.feed(m.timestamp, m.arbitration_id, bytes(m.data))
    seqs = [s.seq for s in dec.samples]
    times = [s.time_us for s in dec.samples]
    assert len(seqs) == 100                       # 50 samples x 2 loops
    assert seqs == list(range(100, 200))          # Seq = file row, continued by the loop
    assert np.all(np.diff(times) == 10000)        # time continues without gap or overlap
    assert times[0] == 1000000


def test_paced_replay_follows_the_recorded_time(rec_csv):
    import can
    bus = can.Bus(interface="virtual", channel="pace")
    try:
        fr = replay.load_frames(str(rec_csv), stop=1.0)
        t0 = time.monotonic()
        replay.send_stream(bus, replay.iterate_loops(fr, 1, True), len(fr), speed=4.0, quiet=True)
        took = time.monotonic() - t0
    finally:
        bus.shutdown()
    assert took >= 0.99 / 4 * 0.95                # never faster than recorded time / speed


def test_replay_errors_are_one_line_and_non_zero(rec_csv, tmp_path, capsys):
    cases = [
        (["replay", str(tmp_path / "missing.csv"), "--to-log", "x.log"], 1, "no such file"),
        (["replay", str(rec_csv)], 2, "either"),
        (["replay", str(rec_csv), "-i", "virtual", "--to-log", "x.log"], 2, "either"),
        (["replay", str(rec_csv), "-i", "nosuchbus", "-c", "x"], 2, "unknown python-can interface"),
        (["replay", str(rec_csv), "--to-log", "x.log", "--speed", "0"], 2, "--speed"),
        (["replay", str(rec_csv), "--to-log", "x.log", "--start", "50"], 1, "no samples"),
    ]
    bad_ext = tmp_path / "rec.txt"
    bad_ext.write_text("x")
    cases.append((["replay", str(bad_ext), "--to-log", "x.log"], 1, "unknown input format"))
    bad_csv = tmp_path / "bad.csv"
    bad_csv.write_text("t_s,gyr_x_rad_s,gyr_y_rad_s,gyr_z_rad_s,acc_x_m_s2,acc_y_m_s2,acc_z_m_s2\n0,0,0,0,0,0,9.8\n0.01,0,zz,0,0,0,9.8\n")
    cases.append((["replay", str(bad_csv), "--to-log", "x.log"], 1, "bad.csv"))
    for argv, rc, text in cases:
        assert attekf(argv) == rc, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and text in err[0], (argv, err)


def test_replay_counts_send_failures_and_goes_on(rec_csv):
    import can

    class Flaky(can.BusABC):
        """A bus that fails every third frame (an interface going down, a full queue)."""
        def __init__(self):
            super().__init__(channel="flaky")
            self.n = 0
            self.ok = 0

        def send(self, msg, timeout=None):
            self.n += 1
            if self.n % 3 == 0:
                raise can.CanOperationError("Failed to transmit: Network is down", 100)
            self.ok += 1

        def _recv_internal(self, timeout):
            return None, False

    bus = Flaky()
    fr = replay.load_frames(str(rec_csv), stop=0.5)
    st = replay.send_stream(bus, replay.iterate_loops(fr, 1, True), len(fr), fast=True, quiet=True)
    assert st.frames == bus.ok and st.failed == len(fr) - bus.ok
    assert st.errors == {"ENETDOWN": st.failed}


def test_replay_marks_the_stream_time_whatever_its_lag(rec_csv, tmp_path, capsys):
    """--mark S:FILE: FILE appears just before the first frame S s or more into the stream goes
    out, by the stream's time, so a replay that lags (here: no pacing at all) marks the same
    frames as one on time."""
    import can

    marks = [tmp_path / "a", tmp_path / "b"]

    class Watch(can.BusABC):
        """Records, per frame sent, which mark files existed."""
        def __init__(self):
            super().__init__(channel="watch")
            self.seen = []

        def send(self, msg, timeout=None):
            self.seen.append(tuple(m.exists() for m in marks))

        def _recv_internal(self, timeout):
            return None, False

    fr = replay.load_frames(str(rec_csv))
    bus = Watch()
    replay.send_stream(bus, replay.iterate_loops(fr, 1, True), len(fr), fast=True, quiet=True,
                       marks=[(2.0, str(marks[1])), (1.5, str(marks[0]))])
    t = np.array([f[0] for f in replay.iterate_loops(fr, 1, True)])
    t = t - t[0]
    assert bus.seen == [(bool(x >= 1.5), bool(x >= 2.0)) for x in t]
    assert 0 < sum(a for a, _ in bus.seen) < len(t)
    done = tmp_path / "done"
    assert attekf(["replay", str(rec_csv), "-i", "virtual", "-c", "mark", "--fast", "-q",
                   "--mark", f"2.5:{done}"]) == 0
    assert done.exists()
    capsys.readouterr()
    for bad in ("1", "x:f", "-1:f", "inf:f"):
        assert attekf(["replay", str(rec_csv), "--to-log", str(tmp_path / "x.log"), "--mark", bad]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--mark" in err[0], err


def test_record_decodes_a_log_to_csv_and_stats(rec_csv, tmp_path):
    """Outputs of a log (encoded here with cantools) come out as estimator-output CSV rows whose
    t_s is the sample time of the input they include."""
    db = cp.database()
    log = tmp_path / "bus.log"
    import can
    fr = replay.load_frames(str(rec_csv), stop=0.1)
    bits = {k: 0 for k in cp.STATUS_BITS}
    EPOCH = 1_767_225_600.0          # bus times as a SocketCAN log has them (2026-01-01, s)
    sent = []
    with can.Logger(str(log)) as lg:
        for k in range(len(fr)):
            lg(can.Message(timestamp=EPOCH + fr.t[k], arbitration_id=int(fr.ids[k]), data=fr.data[k], is_extended_id=False))
            if fr.ids[k] == cp.frame_id("IMU_SYNC") and k % 8 == 7:
                seq = int.from_bytes(fr.data[k][4:6], "little")
                ts = EPOCH + fr.t[k] + 0.0005
                sent.append(ts)
                for name, sig in (("ATT_EULER", {"Roll": 0.1, "Pitch": 0.0, "Yaw": -1.0}),
                                  ("ATT_RATES", {"RateP": 0, "RateQ": 0, "RateR": 0}),
                                  ("ATT_SIGMA", {"SigmaRoll": 0.01, "SigmaPitch": 0.02, "SigmaYaw": 0.1}),
                                  ("ATT_STATUS", {**bits, "Aligned": 1, "AttFlags": 1, "OutIndex": seq // 2})):
                    lg(can.Message(timestamp=ts, arbitration_id=cp.frame_id(name),
                                   data=db.encode_message(name, {**sig, "Seq": seq}), is_extended_id=False))
    out_csv = tmp_path / "att.csv"
    stats = tmp_path / "st.json"
    assert attekf(["record", "-q", "--from-log", str(log), "--csv", str(out_csv), "--stats", str(stats)]) == 0
    out = read_output_csv(str(out_csv))
    assert len(out) == 5
    np.testing.assert_allclose(out.t, [0.01, 0.03, 0.05, 0.07, 0.09], atol=1e-9)
    np.testing.assert_allclose(out.euler[0], [0.1, 0.0, -1.0])
    np.testing.assert_allclose(out.var[0], [0.01 ** 2, 0.02 ** 2, 0.1 ** 2], rtol=1e-6)
    np.testing.assert_allclose(out.extra["latency_s"], 0.0005, atol=2e-6)
    # the bus time keeps its fraction (the candump log has microseconds)
    np.testing.assert_allclose(out.extra["rx_time_s"] - EPOCH, np.array(sent) - EPOCH, atol=1.5e-6)
    st = json.loads(stats.read_text())
    assert st["input_samples"] == 10 and st["outputs"] == 5 and st["latency_us"]["p50"] == pytest.approx(500, abs=2)


def test_record_errors(tmp_path, capsys):
    assert attekf(["record", "--from-log", str(tmp_path / "none.log"), "--csv", "x.csv"]) == 1
    assert "no such file" in capsys.readouterr().err
    assert attekf(["record", "--from-log", str(tmp_path / "none.log")]) == 2
    assert "nothing to write" in capsys.readouterr().err
    assert attekf(["record", "-i", "virtual", "-c", "x", "--from-log", "y.log", "--stats", "s.json"]) == 2
    assert attekf(["record", "-i", "nosuchbus", "-c", "x", "--stats", str(tmp_path / "s.json")]) == 2
    assert "unknown python-can interface" in capsys.readouterr().err
    assert not (tmp_path / "s.json").exists()


def test_record_stops_after_idle_and_counts(tmp_path):
    """A live recording on the virtual bus ends by itself after --idle seconds without frames."""
    import can
    tx = can.Bus(interface="virtual", channel="idle")
    result = {}

    def rec():
        result["rc"] = attekf(["record", "-q", "-i", "virtual", "-c", "idle", "--idle", "0.3",
                               "--duration", "20", "--stats", str(tmp_path / "s.json"),
                               "-o", str(tmp_path / "bus.log")])
    th = threading.Thread(target=rec)
    th.start()
    time.sleep(0.5)
    for k in range(20):
        tx.send(can.Message(arbitration_id=0x555, data=bytes([k]), is_extended_id=False))
    th.join(timeout=15)
    tx.shutdown()
    assert not th.is_alive() and result["rc"] == 0
    st = json.loads((tmp_path / "s.json").read_text())
    assert st["frames"] == 20 and st["by_message"] == {"other": 20}
    assert len(_frames(tmp_path / "bus.log")) == 20


def test_record_idle_ends_while_the_node_sends_heartbeats(tmp_path):
    """--idle counts traffic, not the node's 10 Hz status-only heartbeats (ATT_STATUS with
    Heartbeat, and a counter page) that it sends while its input is stale."""
    import can
    db = cp.database()
    bits = dict({k: 0 for k in cp.STATUS_BITS}, Heartbeat=1, Stale=1)
    status = db.encode_message("ATT_STATUS", {**bits, "AttFlags": 1, "OutIndex": 0, "Seq": 0})
    counter = db.encode_message("ATT_COUNTERS", {"Page": 0, **{s.name: 0 for s in
                                                              db.get_message_by_name("ATT_COUNTERS").signals
                                                              if s.name != "Page"}}, strict=False)
    tx = can.Bus(interface="virtual", channel="hb")
    result = {}

    def rec():
        result["rc"] = attekf(["record", "-q", "-i", "virtual", "-c", "hb", "--idle", "0.3",
                               "--duration", "20", "--stats", str(tmp_path / "s.json")])
    th = threading.Thread(target=rec)
    th.start()
    time.sleep(0.5)
    for k in range(10):
        tx.send(can.Message(arbitration_id=0x555, data=bytes([k]), is_extended_id=False))
    quiet_from = time.monotonic()
    while th.is_alive() and time.monotonic() - quiet_from < 5.0:
        tx.send(can.Message(arbitration_id=cp.frame_id("ATT_STATUS"), data=status, is_extended_id=False))
        tx.send(can.Message(arbitration_id=cp.frame_id("ATT_COUNTERS"), data=counter, is_extended_id=False))
        time.sleep(0.1)
    ended_after = time.monotonic() - quiet_from
    th.join(timeout=15)
    tx.shutdown()
    assert result["rc"] == 0 and ended_after < 2.0, ended_after
    st = json.loads((tmp_path / "s.json").read_text())
    assert st["by_message"]["other"] == 10 and st["heartbeats"] >= 1
