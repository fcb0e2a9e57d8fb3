"""Hardware-in-loop test on vcan0, on the first backend of hal/tools/vcan_run.py that works
here (the host's CAN, user-mode Linux or QEMU; docs/hil.md).

One guest boot runs three scenarios with hal/tools/hil_scenario.sh (attekf-node on vcan0,
`attekf record` logging the bus, `attekf replay` injecting the stream at recorded time):

  clean-sim     a simulated recording, 8 s at 200 Hz (always)
  clean-broad   6 s of a real BROAD recording at 285.7 Hz (skipped if the data is absent)
  faults        6 s at 200 Hz with dropped, duplicated, reordered, wrong-length and unknown-id
                frames injected, and vcan0 taken down for 0.3 s in the middle

and the same frame logs go through the node's virtual backend (attekf-node --replay) on the host.
The clean runs must lose no input frame, produce every expected output, and equal the virtual
run; the fault run must count every injected fault and recover from the bus outage.
Runtime: about 40 s under UML (boot 2 s, three Python-heavy scenarios, 20 s of paced replay).
"""

from __future__ import annotations

import json
import os
import shlex

import numpy as np
import pytest

import hilutil
import prereq
from hilutil import report

RATE_SIM_HZ = 200.0
OUT_PERIOD_US = 10000        # the node's default output rate, 100 Hz
BROAD_TRIAL = "07_undisturbed_fast_rotation_B.hdf5"
FAULT_SECONDS = 6.0
LATE_PART = 1000             # sample of the late faults (after the bounce)
BOUNCE = (3.0, 0.3)          # vcan0 down AFTER s after the first frame, for DOWN s
TIMING_FLAGS = 0x0002 | 0x0020 | 0x0800   # Stale, LinkError, Heartbeat: depend on wall time


def _sim(duration: float, seed: int):
    from attekf.sim import SimConfig, simulate
    return simulate(SimConfig(duration_s=duration, rate_hz=RATE_SIM_HZ, seed=seed))


@pytest.fixture(scope="module")
def hil(tmp_path_factory, vcan, node):
    """Prepares the inputs, runs the virtual runs on the host and the scenarios on vcan0."""
    from attekf.io import read_recording, write_recording_csv
    root = tmp_path_factory.mktemp("hil")
    scen = {}

    rec = _sim(8.0, seed=11)
    write_recording_csv(str(root / "sim.csv"), rec)
    scen["clean-sim"] = dict(input=root / "sim.csv", rec=rec, args=[])

    broad = prereq.BROAD_DIR / BROAD_TRIAL
    if broad.is_file():
        full = read_recording(str(broad))
        a = int(20.0 * full.rate_hz)
        brec = full.slice(a, a + int(6.0 * full.rate_hz))
        brec.t = brec.t - brec.t[0]
        write_recording_csv(str(root / "broad.csv"), brec)
        scen["clean-broad"] = dict(input=root / "broad.csv", rec=read_recording(str(root / "broad.csv")), args=[])

    frec = _sim(FAULT_SECONDS, seed=12)
    plan = hilutil.inject_faults(hilutil.recording_frames(frec), len(frec), LATE_PART)
    hilutil.write_log(root / "faults.log", plan.frames)
    scen["faults"] = dict(input=root / "faults.log", rec=frec, plan=plan,
                          args=["--bounce", f"{BOUNCE[0]},{BOUNCE[1]}"])

    # The same frames through the virtual backend, on the host.
    for name, s in scen.items():
        if name.startswith("clean"):
            s["frames_log"] = root / f"{name}.frames.log"
            hilutil.write_log(s["frames_log"], hilutil.recording_frames(s["rec"]))
        else:
            s["frames_log"] = s["input"]
        s["virtual_log"] = root / f"{name}.virtual.log"
        s["virtual"] = hilutil.run_virtual(s["frames_log"], s["virtual_log"], root / f"{name}.virtual.json")
        s["dir"] = root / name

    # Interface deleted and re-created while the node runs (can-utils' canplayer sends).
    rrec = _sim(4.0, seed=13)
    rframes = hilutil.recording_frames(rrec)
    hilutil.write_candump(root / "recreate1.log", rframes[:400])
    hilutil.write_candump(root / "recreate2.log", rframes[400:800])
    rdir = root / "recreate"
    rdir.mkdir()
    q = lambda p: shlex.quote(str(p))
    recreate = (
        f"{q(node)} -i vcan0 --ready-file {q(rdir / 'ready')} --stats {q(rdir / 'node.json')} "
        f"> {q(rdir / 'node.log')} 2>&1 & P=$!; "
        f"while [ ! -f {q(rdir / 'ready')} ]; do sleep 0.02; done; "
        f"canplayer -I {q(root / 'recreate1.log')} vcan0=vcan0; sleep 0.2; "
        "ip link del vcan0; sleep 0.3; ip link add dev vcan0 type vcan; ip link set up vcan0; sleep 0.5; "
        f"canplayer -I {q(root / 'recreate2.log')} vcan0=vcan0; sleep 0.3; kill -TERM $P; wait $P; "
        f"echo $? > {q(rdir / 'status')}")

    script = recreate + "; " + "; ".join(
        " ".join(shlex.quote(str(a)) for a in [hilutil.SCENARIO, s["dir"], "vcan0", s["input"], *s["args"]])
        + f" > {shlex.quote(str(root / (name + '.scenario.log')))} 2>&1"
        for name, s in scen.items()) + "; true"
    env = dict(os.environ, ATTEKF_NODE=str(node))
    res = vcan.run(script, env=env, timeout=600)
    hilutil.FULL_SUITE_BACKEND.append(res.mode)
    report(f"HIL ran on backend {res.mode}, {res.seconds:.1f} s wall time (command started after "
           f"{res.boot_seconds:.1f} s)" + "".join(f"; {n}" for n in res.notes))
    for name, s in scen.items():
        d = s["dir"]
        status = (d / "status").read_text().strip() if (d / "status").exists() else "missing"
        assert status == "replay=0 node=0 record=0", (
            f"{name}: scenario failed ({status}): "
            + (root / f"{name}.scenario.log").read_text()[-2000:]
            + "".join((d / f).read_text()[-1000:] for f in ("node.log", "record.log", "replay.log")
                      if (d / f).exists()))
        s["node"] = json.loads((d / "node.json").read_text())
        s["record"] = json.loads((d / "record.json").read_text())
        s["replay"] = json.loads((d / "replay.json").read_text())
        s["ifstats"] = hilutil.read_ifstats(d / "ifstats.txt")
        s["live_out"] = hilutil.decode_outputs(d / "bus.log")
        s["virt_out"] = hilutil.decode_outputs(s["virtual_log"])
    hil_recreate = {"node": json.loads((rdir / "node.json").read_text()) if (rdir / "node.json").exists() else None,
                    "log": (rdir / "node.log").read_text() if (rdir / "node.log").exists() else "",
                    "status": (rdir / "status").read_text().strip() if (rdir / "status").exists() else "missing"}
    scen["_recreate"] = hil_recreate
    return scen


CLEAN = ["clean-sim", "clean-broad"]


def _scenario(hil, name):
    if name not in hil:
        prereq.unavailable(f"{prereq.BROAD_DIR / BROAD_TRIAL} not present (real data is not part of "
                           f"the repository; set ATTEKF_BROAD_DIR)")
    return hil[name]


@pytest.mark.parametrize("name", CLEAN)
def test_zero_input_frames_lost(hil, name):
    s = _scenario(hil, name)
    n_frames = len(hilutil.read_log(s["frames_log"]))
    c = s["node"]["counters"]
    assert s["replay"]["failed"] == 0
    assert s["replay"]["frames"] == n_frames
    assert c["rx_frames"] == n_frames, "frames lost between replay and node"
    assert c["rx_overflow"] == 0
    for k in ("foreign", "bad_dlc", "duplicate", "late", "incomplete", "discarded", "gaps",
              "missing", "time_errors", "resync", "realign", "link_down", "tx_errors", "ekf_rejected"):
        assert c[k] == 0, k
    assert c["samples"] == len(s["rec"])
    r = s["record"]
    assert r["input_samples"] == len(s["rec"]) and r["input_seq_missing"] == 0
    st = s["ifstats"]
    assert st["end"]["rx_dropped"] == st["start"]["rx_dropped"], "the kernel dropped frames on vcan0"
    report(f"{name}: {n_frames} input frames sent, {c['rx_frames']} received by the node, "
           f"{c['rx_overflow']} kernel drops, {r['input_seq_missing']} missing on the bus")


@pytest.mark.parametrize("name", CLEAN)
def test_every_expected_output_present(hil, name):
    from attekf import canproto
    s = _scenario(hil, name)
    expected = canproto.output_schedule(canproto.time_us(s["rec"].t), OUT_PERIOD_US) & 0xFFFF
    live = s["live_out"]
    assert [r.seq for r in live.rows] == expected.tolist()
    assert live.broken == 0
    assert s["record"]["output_index_missing"] == 0
    assert s["node"]["counters"]["outputs"] == expected.size
    # the last published counters agree with the node's own
    assert live.counters["samples"] <= s["node"]["counters"]["samples"]
    assert all(r.flags & 0x1 for r in live.rows[-10:]), "not aligned at the end"


@pytest.mark.parametrize("name", CLEAN)
def test_attitude_equals_virtual_run(hil, name):
    from attekf import canproto
    s = _scenario(hil, name)
    live, virt = s["live_out"].rows, s["virt_out"].rows
    assert [r.seq for r in live] == [r.seq for r in virt]
    e_l = np.array([r.euler + r.rates + r.sigma for r in live])
    e_v = np.array([r.euler + r.rates + r.sigma for r in virt])
    lsb = np.array([canproto.resolution("ATT_EULER", "Roll")] * 3 + [canproto.resolution("ATT_RATES", "RateP")] * 3
                   + [canproto.resolution("ATT_SIGMA", "SigmaRoll")] * 3)
    diff = np.abs(e_l - e_v) / lsb
    assert diff.max() <= 1.0 + 1e-6, f"differs by {diff.max():.2f} LSB"
    assert [r.att_flags for r in live] == [r.att_flags for r in virt]
    assert [r.flags & ~TIMING_FLAGS for r in live] == [r.flags & ~TIMING_FLAGS for r in virt]
    same = int(np.all(diff == 0, axis=1).sum())
    report(f"{name}: {len(live)} outputs, {same} bit-identical to the virtual-backend run, "
           f"max difference {diff.max():.0f} LSB")


@pytest.mark.parametrize("name", CLEAN)
def test_latency_measured(hil, name):
    s = _scenario(hil, name)
    bus = s["record"]["latency_us"]
    nd = s["node"]["latency_us"]
    assert bus["count"] == len(s["live_out"].rows) and bus["p50"] is not None
    assert nd["count"] == s["node"]["counters"]["outputs"]
    assert 0 < bus["p50"] <= bus["p99"]
    report(f"{name}: frame-to-output latency on the bus (IMU_SYNC -> ATT_EULER): p50 {bus['p50']:.0f} us, "
           f"p99 {bus['p99']:.0f} us, max {bus['max']:.0f} us; node-side (kernel rx -> frames sent): "
           f"p50 {nd['p50']} us, p99 {nd['p99']} us")


# ---------------------------------------------------------------------------------------------
# Fault injection
# ---------------------------------------------------------------------------------------------
FRAME_LEVEL = ("foreign", "bad_dlc", "duplicate", "late")


def test_faults_virtual_counts_exactly(hil):
    s = hil["faults"]
    c = s["virtual"]["counters"]
    for k, v in s["plan"].expected.items():
        assert c[k] == v, f"{k}: {c[k]} != {v}"
    assert c["rx_frames"] == len(s["plan"].frames)
    assert c["samples"] == len(s["rec"]) - 3 - 1   # three lost, one discarded


def test_faults_live_counters_and_flags(hil):
    s = hil["faults"]
    exp = s["plan"].expected
    c = s["node"]["counters"]
    rp = s["replay"]
    assert rp["failed"] > 0, "the bus outage did not make any send fail"
    # A frame whose send() succeeds just as vcan0 goes down can be dropped by the kernel before
    # any socket sees it; the interface counts it in rx_dropped. Every other frame must arrive.
    st = s["ifstats"]
    dropped = st["end"]["rx_dropped"] - st["start"]["rx_dropped"]
    lost = rp["frames"] - c["rx_frames"]
    assert 0 <= lost <= dropped, (f"{lost} frames sent while vcan0 was up did not reach the node, "
                                  f"the kernel counted {dropped} drops on vcan0")
    assert c["rx_overflow"] == 0
    for k in FRAME_LEVEL:
        assert c[k] == exp[k], f"{k}: {c[k]} != {exp[k]}"
    assert c["link_down"] == 1
    # the outage adds one gap, and may cut one sample in half
    assert c["gaps"] == exp["gaps"] + 1
    assert c["missing"] > exp["missing"]
    assert exp["incomplete"] <= c["incomplete"] <= exp["incomplete"] + 1
    assert exp["discarded"] <= c["discarded"] <= exp["discarded"] + 1
    flags = 0
    for r in s["live_out"].rows:
        flags |= r.flags
    # a latched flag leaves with the next output that is sent; around the outage the stream is
    # stale and that output can be a heartbeat, so the heartbeats' flags count too
    for _t, f, _i in s["live_out"].heartbeats:
        flags |= f
    for name in ("Gap", "FrameError", "Incomplete", "LinkError"):
        assert flags & canproto_bits()[name], f"status flag {name} never set"
    # stale three times: before the replay starts, during the outage, after the stream ends; the
    # heartbeats during the outage cannot be sent (counted), the others are on the bus
    assert c["stale"] >= 3
    assert c["tx_errors"] > 0
    hb = s["live_out"].heartbeats
    assert hb and all(f & canproto_bits()["Stale"] for _t, f, _i in hb)
    # every counter reached the bus in the ATT_COUNTERS pages
    for k in FRAME_LEVEL + ("link_down", "gaps"):
        assert s["live_out"].counters[k] == c[k], k
    report(f"faults: node counted foreign={c['foreign']} bad_dlc={c['bad_dlc']} duplicate={c['duplicate']} "
           f"late={c['late']} incomplete={c['incomplete']} discarded={c['discarded']} gaps={c['gaps']} "
           f"missing={c['missing']} link_down={c['link_down']}; replay: {rp['failed']} sends failed "
           f"while vcan0 was down; node received {c['rx_frames']} of the {rp['frames']} frames sent, "
           f"vcan0 counted {dropped} kernel drops around the outage")


def canproto_bits():
    from attekf import canproto
    return canproto.STATUS_BITS


def test_faults_live_equals_virtual_before_outage_and_recovers(hil):
    s = hil["faults"]
    live, virt = s["live_out"].rows, s["virt_out"].rows
    gap_rows = [i for i, r in enumerate(live) if r.seq > 500 and (r.flags & canproto_bits()["Gap"])]
    assert gap_rows, "no output after the outage carries the Gap flag"
    first_after = gap_rows[0]
    lost_from = live[first_after - 1].seq
    before_l = [r for r in live if r.seq <= lost_from]
    before_v = [r for r in virt if r.seq <= lost_from]
    assert [r.seq for r in before_l] == [r.seq for r in before_v]
    assert [r.euler for r in before_l] == [r.euler for r in before_v]
    # after the outage: outputs continue to the end of the stream, aligned, near the virtual run
    last = live[-1]
    assert last.seq == virt[-1].seq and last.flags & 0x1
    assert max(abs(a - b) for a, b in zip(last.euler[:2], virt[-1].euler[:2])) < 0.05


def test_interface_deleted_and_recreated(hil):
    """`ip link del vcan0` + re-create: the node's socket is gone (ENODEV); it re-opens the
    interface by name and carries on, without a restart."""
    r = hil["_recreate"]
    assert r["status"] == "0", r["log"]
    c = r["node"]["counters"]
    assert c["link_down"] == 1
    assert c["rx_frames"] == 800 and c["samples"] == 200, c
    assert c["gaps"] == 0 and c["rx_overflow"] == 0
    assert "link_down" in r["log"] and "link_up" in r["log"]
    assert c["outputs"] == 100                      # 200 Hz samples, 100 Hz outputs, none lost
    report(f"interface re-created: node re-opened vcan0 and processed all {c['samples']} samples "
           f"({c['tx_errors']} output frames could not be sent while it was gone)")
