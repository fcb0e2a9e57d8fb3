"""Ctrl-C and SIGTERM in the middle of the work: the commands stop promptly, say what was left,
exit 130, and never leave an output that looks complete (docs/host_tools.md, "Exit status,
outputs and interruption"). Signals go to the whole process group, as a terminal's Ctrl-C
does, so that pool workers get it too."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from attekf.cli import main as attekf

ATTEKF = str(Path(sys.executable).parent / "attekf")


def _as_foreground_job():
    # A shell starts a background job with SIGINT ignored, and Python keeps an ignored SIGINT
    # (no KeyboardInterrupt): when the suite itself runs in the background (a CI runner, nohup),
    # the commands under test would inherit that. Ctrl-C reaches a terminal's foreground job
    # with the default disposition, so restore it.
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start(*argv):
    return subprocess.Popen([ATTEKF, *map(str, argv)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True, preexec_fn=_as_foreground_job)


def wait_for(cond, proc, timeout=60.0):
    t0 = time.monotonic()
    while not cond():
        assert proc.poll() is None, f"finished before the signal: {proc.communicate()}"
        assert time.monotonic() - t0 < timeout, "condition never met"
        time.sleep(0.02)


def partials(d: Path):
    """Temporary outputs being written; not the probe files with which the output checks test a
    directory before the work (created and removed at once: a signal then hits the set-up)."""
    return [p for p in d.rglob(".partial-*") if not p.name.endswith("-probe")] if d.exists() else []


def interrupt(proc, sig=signal.SIGINT, timeout=120.0):
    """Signals the process group; the generous timeout only guards against a hang on a loaded
    machine (promptness itself is asserted where it is the point: the record test)."""
    t0 = time.monotonic()
    os.killpg(proc.pid, sig)
    out, err = proc.communicate(timeout=timeout)
    return proc.returncode, out, err, time.monotonic() - t0


def test_eval_directory_interrupted_leaves_nothing(tmp_path):
    recs = tmp_path / "recs"
    # enough recordings that the signal lands while work remains after the first plot, even
    # when the machine is fast or the poll below is late
    for k in range(6):
        assert attekf(["sim", "-q", str(recs / f"r{k}.csv"), "--duration", "120", "--seed", str(k)]) == 0
    out = tmp_path / "out"
    out.mkdir()
    (out / "table.txt").write_text("an earlier run\n")
    p = start("eval", recs, "--out", out, "-q")
    wait_for(lambda: partials(out), p)          # the first plot is being written
    rc, stdout, err, _ = interrupt(p)
    assert rc == 130, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "attekf eval: interrupted: after" in lines[0] and "nothing written" in lines[0], err
    assert "Traceback" not in err and stdout == ""
    assert sorted(os.listdir(out)) == ["table.txt"] and (out / "table.txt").read_text() == "an earlier run\n"


def test_eval_sigterm_cleans_up_too(tmp_path):
    for k in range(2):
        assert attekf(["sim", "-q", str(tmp_path / f"r{k}.csv"), "--duration", "60", "--seed", str(k)]) == 0
    out = tmp_path / "new" / "deeper"
    p = start("eval", tmp_path / "r0.csv", tmp_path / "r1.csv", "--out", out, "-q")
    wait_for(lambda: partials(tmp_path), p)
    rc, _, err, _ = interrupt(p, signal.SIGTERM)
    assert rc == 130 and "interrupted" in err and "Traceback" not in err, err
    assert not (tmp_path / "new").exists()     # the directories made for the outputs go too


def test_replay_to_log_interrupted_leaves_no_log(tmp_path):
    # about 5 s of writing the log (the partial file's lifetime), so the signal lands inside it
    assert attekf(["sim", "-q", str(tmp_path / "long.hdf5"), "--duration", "600", "--rate", "400"]) == 0
    log = tmp_path / "frames.log"
    p = start("replay", tmp_path / "long.hdf5", "--to-log", log, "-q")
    wait_for(lambda: partials(tmp_path), p)
    time.sleep(0.2)
    rc, _, err, _ = interrupt(p)
    assert rc == 130, err
    assert "attekf replay: interrupted:" in err and "frames.log not written" in err and "Traceback" not in err
    assert not log.exists() and not partials(tmp_path)


def test_record_from_log_honours_ctrl_c(tmp_path):
    log = tmp_path / "big.log"
    with open(log, "w") as fh:
        for k in range(600_000):
            fh.write(f"({k * 1e-4:.6f}) vcan0 555#0011223344556677\n")
    p = start("record", "--from-log", log, "-o", tmp_path / "copy.log", "--stats", tmp_path / "s.json", "-q")
    wait_for(lambda: partials(tmp_path), p)     # the -o log is open: reading has begun
    time.sleep(0.3)
    rc, _, err, took = interrupt(p)
    assert rc == 130, err
    assert "attekf record: interrupted: after" in err and "frames of" in err and "nothing written" in err, err
    assert took < 10.0                          # stops reading, does not finish the log first
    assert sorted(os.listdir(tmp_path)) == ["big.log"]


def test_record_live_ctrl_c_is_the_normal_stop(tmp_path):
    """On a bus, Ctrl-C is how listening ends: the outputs are written, complete, exit 0."""
    ready = tmp_path / "ready"
    p = start("record", "-i", "virtual", "-c", "t", "-o", tmp_path / "bus.log", "--stats", tmp_path / "s.json",
              "--ready-file", ready, "-q")
    wait_for(ready.exists, p)
    rc, _, err, _ = interrupt(p)
    assert rc == 0, err
    assert (tmp_path / "s.json").exists() and (tmp_path / "bus.log").exists() and not partials(tmp_path)


def test_bench_interrupted_with_workers(tmp_path):
    data = tmp_path / "data"
    for k in range(4):
        assert attekf(["sim", "-q", str(data / f"t{k}.hdf5"), "--duration", "300", "--rate", "200",
                       "--seed", str(k)]) == 0
    out = tmp_path / "out"
    p = start("bench", "--data", data, "--methods", "madgwick-9d,mahony-9d", "--jobs", "2", "--out", out, "-q")
    children = Path(f"/proc/{p.pid}/task/{p.pid}/children")
    if not children.exists():
        pytest.skip("this kernel does not list child processes in /proc")
    wait_for(lambda: len(children.read_text().split()) >= 2, p)   # the pool's workers run
    time.sleep(0.3)
    rc, stdout, err, _ = interrupt(p)
    assert rc == 130, err
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and "attekf bench: interrupted:" in lines[0], err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    assert not out.exists()
