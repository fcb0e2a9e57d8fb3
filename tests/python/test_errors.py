"""Every failure a user can meet in the host tools ends cleanly: one line on stderr naming the
file and the line or field, the documented exit status (docs/host_tools.md, "Exit status,
outputs and interruption"), no traceback, and no output file left behind.

Most cases run the command in this process (attekf.cli.main, fast); the ones about processes
(the console script, the node, the virtual bus) run the real programs."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from attekf.cli import main as attekf
from attekf.io import read_output_csv, read_recording, write_recording_csv
from attekf.sim import SimConfig, simulate

REPO = Path(__file__).resolve().parents[2]
ATTEKF = Path(sys.executable).parent / "attekf"
NODE = Path(os.environ.get("ATTEKF_NODE", REPO / "build" / "host" / "firmware" / "app" / "attekf-node"))
HEADER = "t_s,gyr_x_rad_s,gyr_y_rad_s,gyr_z_rad_s,acc_x_m_s2,acc_y_m_s2,acc_z_m_s2"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A small recording (CSV and HDF5), its input frames as a candump log and as BLF."""
    import can
    d = tmp_path_factory.mktemp("errors")
    rec = simulate(SimConfig(duration_s=4.0, rate_hz=100.0, seed=11, initial_rest_s=1.0))
    write_recording_csv(str(d / "rec.csv"), rec)
    assert attekf(["sim", "-q", str(d / "rec.hdf5"), "--duration", "4", "--seed", "11", "--rest", "1"]) == 0
    assert attekf(["replay", "-q", str(d / "rec.csv"), "--to-log", str(d / "in.log")]) == 0
    with can.Logger(str(d / "in.blf")) as lg:
        for m in can.LogReader(str(d / "in.log")):
            lg(m)
    return d


def listing(d: Path):
    return sorted(str(p.relative_to(d)) for p in d.rglob("*"))


def one_line_error(capsys, command: str) -> str:
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith(f"attekf {command}: error: "), err
    assert "Traceback" not in err
    return lines[0]


def check(capsys, argv, code, *fragments, workdir=None):
    """Runs argv; asserts the exit status, one error line holding every fragment, and that
    workdir (if given) holds the same files afterwards."""
    before = listing(workdir) if workdir else None
    assert attekf([str(a) for a in argv]) == code, argv
    line = one_line_error(capsys, argv[0])
    for f in fragments:
        assert str(f) in line, (f, line)
    if workdir:
        assert listing(workdir) == before, "output left behind"
    return line


# ---------------------------------------------------------------------------------------------
# node -> record -> eval, with the real attekf-node
# ---------------------------------------------------------------------------------------------
def test_node_record_eval_chain(files, tmp_path, capsys):
    if not os.access(NODE, os.X_OK):
        pytest.fail(f"{NODE} is not built: cmake --build build/host (or set ATTEKF_NODE)", pytrace=False)
    p = subprocess.run([str(NODE), "--replay", str(files / "in.log"), "-o", str(tmp_path / "out.log"),
                        "-l", "error"], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    att = tmp_path / "att.csv"
    assert attekf(["record", "-q", "--from-log", str(tmp_path / "out.log"), "--csv", str(att)]) == 0
    out = read_output_csv(str(att))
    # no sync frames in the node's output log: latency unknown, written empty, read as NaN
    assert np.isnan(out.extra["latency_s"]).all()
    # outputs before alignment are empty cells, not 0,0,0
    text = att.read_text().splitlines()
    assert text[1].split(",")[1:4] == ["", "", ""]
    not_aligned = (out.extra["node_flags"].astype(int) & 1) == 0
    assert not_aligned.any() and np.isnan(out.euler[not_aligned]).all()
    assert np.isfinite(out.euler[~not_aligned]).all()
    capsys.readouterr()
    js = tmp_path / "r.json"
    assert attekf(["eval", "-q", str(files / "rec.hdf5"), "--output-csv", str(att), "--json", str(js)]) == 0
    recorded = json.loads(js.read_text())["trials"][0]
    assert recorded["counts"]["scored"] > 250
    assert attekf(["eval", "-q", str(files / "rec.hdf5"), "--json", str(js)]) == 0
    direct = json.loads(js.read_text())["trials"][0]
    # the node is the same estimator (float build); only the CAN quantisation differs
    assert recorded["rmse_deg"]["total"] == pytest.approx(direct["rmse_deg"]["total"], abs=0.2)


# ---------------------------------------------------------------------------------------------
# python-can's virtual bus between two processes
# ---------------------------------------------------------------------------------------------
def test_virtual_interface_across_processes_is_called_out(files, tmp_path):
    rec = subprocess.Popen([str(ATTEKF), "record", "-q", "-i", "virtual", "-c", "x", "--duration", "3",
                            "--stats", str(tmp_path / "s.json")], stderr=subprocess.PIPE, text=True)
    rep = subprocess.run([str(ATTEKF), "replay", "-q", str(files / "rec.csv"), "-i", "virtual", "-c", "x",
                          "--fast"], capture_output=True, text=True, timeout=60)
    _, rec_err = rec.communicate(timeout=60)
    assert rep.returncode == 0 and rec.returncode == 0
    for err in (rep.stderr, rec_err):
        assert "'virtual' interface reaches only buses in this same process" in err, err
        assert "Traceback" not in err
    assert "received no frames" in rec_err
    assert json.loads((tmp_path / "s.json").read_text())["frames"] == 0


# ---------------------------------------------------------------------------------------------
# Outputs checked before the work; no partial output
# ---------------------------------------------------------------------------------------------
def test_unwritable_outputs_fail_first_with_one_line(files, tmp_path, capsys):
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    bad_rec = tmp_path / "bad.csv"
    bad_rec.write_text(HEADER + "\n0,zz,0,0,0,0,9.8\n")
    proc = Path("/proc/attekf-no-such-dir")
    cases = [
        # the output is reported although the input is bad too: outputs are checked first
        (["eval", bad_rec, "--out", blocker], 1, "afile: exists and is not a directory", "--out"),
        (["eval", bad_rec, "--json", blocker / "r.json"], 1, "afile is not a directory", "--json"),
        (["eval", bad_rec, "--json", tmp_path], 1, "is a directory", "--json"),
        (["eval", bad_rec, "--json", proc / "r.json"], 1, "cannot write (--json)"),
        (["bench", "--data", tmp_path / "none", "--json", blocker / "r.json"], 1, "--json"),
        (["bench", "--data", tmp_path / "none", "--markdown", blocker / "a.md"], 1, "--markdown"),
        (["bench", "--data", tmp_path / "none", "--out", blocker], 1, "--out"),
        (["replay", files / "rec.csv", "--to-log", blocker / "x.log"], 1, "--to-log", "afile is not a directory"),
        (["replay", files / "rec.csv", "--to-log", tmp_path / "x.log", "--stats", blocker / "s.json"], 1, "--stats"),
        (["record", "--from-log", files / "in.log", "--stats", blocker / "s.json"], 1, "--stats"),
        (["record", "--from-log", files / "in.log", "--csv", proc / "a.csv"], 1, "--csv"),
        (["record", "--from-log", files / "in.log", "-o", blocker / "o.log"], 1, "-o"),
        (["sim", blocker / "x.csv"], 1, "afile is not a directory"),
        (["replay", files / "rec.csv", "--to-log", tmp_path / "x.xyz"], 2, "unknown CAN log format"),
        (["record", "--from-log", files / "in.log", "--csv", files / "in.log"], 2, "overwrite the input"),
        (["eval", files / "rec.csv", "--json", tmp_path / "j.json", "--out", tmp_path / "o",
          "--no-plot"], 0, None),
    ]
    for argv, code, *fragments in cases:
        if code == 0:
            assert attekf([str(a) for a in argv]) == 0
            capsys.readouterr()
            continue
        check(capsys, argv, code, *fragments, workdir=tmp_path)


def test_failing_interface_leaves_no_log_file(files, tmp_path, capsys):
    """socketcan on a missing interface (or a kernel without CAN): exit 1, no empty -o."""
    check(capsys, ["record", "-i", "socketcan", "-c", "attekfnone0", "-o", tmp_path / "bus.log",
                   "--csv", tmp_path / "a.csv"], 1, "cannot open socketcan channel attekfnone0", workdir=tmp_path)


# ---------------------------------------------------------------------------------------------
# Inputs
# ---------------------------------------------------------------------------------------------
def test_settings_file_errors(files, tmp_path, capsys):
    binary = tmp_path / "s.json"
    binary.write_bytes(b"{\n\x89PNG\r\n\x1a\n\x00\x00")
    check(capsys, ["eval", files / "rec.csv", "--settings", binary], 1, "s.json", "line 2", "not a text file")
    binary.write_text('{"accel_noise": "abc"}')
    check(capsys, ["eval", files / "rec.csv", "--settings", binary], 1, "s.json", "accel_noise", "not a number")
    binary.write_text('{"accel_noise": 0.3,\n "bogus": }')
    check(capsys, ["eval", files / "rec.csv", "--settings", binary], 1, "s.json: line 2: invalid JSON")
    binary.write_text('{"no_such_setting": 1}')
    check(capsys, ["eval", files / "rec.csv", "--settings", binary], 2, "s.json", "unknown setting 'no_such_setting'")
    check(capsys, ["bench", "--settings", str(binary), "--methods", "ours-9d"], 2, "s.json", "no_such_setting")


@pytest.mark.parametrize("text, fragment", [
    ("(0.000000) vcan0 100#0011223344556677\n(0.010000) vcan0 10G#00\n", "line 2: id '10G' is not 1 to 8 hexadecimal"),
    ("(0.000000) vcan0\n", "line 1: not a candump line"),
    ("(0.000000) vcan0 100#001\n", "line 1: data '001' is not whole bytes"),
    ("(0.000000) vcan0 100#001122334455667788\n", "line 1: data has 9 bytes"),
    ("(0.0x0) vcan0 100#00\n", "line 1: time stamp '(0.0x0)'"),
    ("(0.000000) vcan0 800#00\n", "line 1: id 800 beyond 0x7FF"),
    ("(0.000000) vcan0 100#00 junk\n", "line 1: unexpected 'junk'"),
    ("(0.000000) vcan0 100#00\n(0.010000) vcan0 100#0011", "line 2: the last line has no line end"),
    ("", "no CAN data frames"),
    ("\n# only a comment\n", "no CAN data frames"),
])
def test_bad_candump_lines_name_the_line_replay_and_record_agree(tmp_path, capsys, text, fragment):
    log = tmp_path / "bad.log"
    log.write_text(text)
    for argv in (["replay", log, "--to-log", tmp_path / "x.log"],
                 ["record", "--from-log", log, "--csv", tmp_path / "a.csv", "-o", tmp_path / "c.blf"]):
        check(capsys, argv, 1, "bad.log", fragment, workdir=tmp_path)


def test_corrupt_and_truncated_blf(files, tmp_path, capsys):
    data = (files / "in.blf").read_bytes()
    cases = {"half.blf": (data[: len(data) // 2], "truncated"),
             "head.blf": (data[:200], "truncated"),
             "noise.blf": (b"LOGG" + np.random.default_rng(1).bytes(400), "not a BLF file"),
             "flipped.blf": (data[:150] + b"\xff" * 40 + data[190:], "corrupt"),
             "tiny.blf": (b";;", "not a BLF file")}
    for name, (content, fragment) in cases.items():
        (tmp_path / name).write_bytes(content)
        for argv in (["record", "--from-log", tmp_path / name, "--csv", tmp_path / "a.csv"],
                     ["replay", tmp_path / name, "--to-log", tmp_path / "x.log"]):
            check(capsys, argv, 1, name, fragment, workdir=tmp_path)
    # the complete file reads
    assert attekf(["record", "-q", "--from-log", str(files / "in.blf"), "--stats", str(tmp_path / "s.json")]) == 0
    assert json.loads((tmp_path / "s.json").read_text())["input_samples"] == 401


def test_truncated_asc(files, tmp_path, capsys):
    import can
    with can.Logger(str(tmp_path / "full.asc")) as lg:
        for m in can.LogReader(str(files / "in.log")):
            lg(m)
    text = (tmp_path / "full.asc").read_text()
    (tmp_path / "cut.asc").write_text(text[: len(text) // 2])
    check(capsys, ["replay", tmp_path / "cut.asc", "--to-log", tmp_path / "x.log"], 1, "cut.asc", "truncated")
    assert attekf(["replay", "-q", str(tmp_path / "full.asc"), "--to-log", str(tmp_path / "x.log")]) == 0


def test_csv_with_byte_order_mark_is_read(files, tmp_path, capsys):
    text = (files / "rec.csv").read_text()
    (tmp_path / "bom.csv").write_bytes(b"\xef\xbb\xbf" + text.replace("\n", "\r\n").encode())
    rec = read_recording(str(tmp_path / "bom.csv"))
    assert len(rec) == 401 and rec.quat_ref is not None
    assert attekf(["eval", "-q", str(tmp_path / "bom.csv"), "--no-plot"]) == 0


@pytest.mark.parametrize("sep, name", [(";", "';'"), ("\t", "tab")])
def test_other_delimiters_are_named(tmp_path, capsys, sep, name):
    rows = [HEADER] + [f"{k * 0.01:.2f},0,0,0,0,0,9.81" for k in range(5)]
    (tmp_path / "semi.csv").write_text("\n".join(r.replace(",", sep) for r in rows) + "\n")
    check(capsys, ["eval", tmp_path / "semi.csv"], 1, "semi.csv: line 1", f"separated by {name}")
    # a header with commas but rows with decimal commas and ';'
    (tmp_path / "mixed.csv").write_text(HEADER + "\n" + "0;0,1;0;0;0;0;9,81\n")
    check(capsys, ["replay", tmp_path / "mixed.csv", "--to-log", tmp_path / "x.log"], 1,
          "mixed.csv: line 2", "separated by ';'")


def test_utf16_csv_is_named(files, tmp_path, capsys):
    (tmp_path / "u16.csv").write_bytes((files / "rec.csv").read_text().encode("utf-16"))
    check(capsys, ["eval", tmp_path / "u16.csv"], 1, "u16.csv: UTF-16 text")


# ---------------------------------------------------------------------------------------------
# Exit status
# ---------------------------------------------------------------------------------------------
def test_usage_errors_exit_2(files, tmp_path, capsys):
    rec = files / "rec.csv"
    cases = [
        (["eval", rec, "--set", "accel_noise=abc"], "--set 'accel_noise=abc': 'abc' is not a number"),
        (["eval", rec, "--set", "accel_noise=nan"], "not a finite number"),
        (["eval", rec, "--set", "no_such=1"], "unknown setting 'no_such'"),
        (["eval", rec, "--set", "accel_noise"], "expected NAME=VALUE"),
        (["eval", rec, "--time-offset", "x"], "argument --time-offset: invalid number value: 'x'"),
        (["bench", "--set", "accel_noise=abc"], "'abc' is not a number"),
        (["bench", "--methods", "ours-9d", "--set", "no_such=1"], "unknown setting 'no_such'"),
        (["bench", "--fusion-set", "nope=1"], "unknown Fusion setting"),
        (["bench", "--jobs", "0"], "argument --jobs/-j: invalid integer >= 1 value: '0'"),
        (["replay", rec, "-i", "nosuchbus", "-c", "x"], "-i nosuchbus: unknown python-can interface"),
        (["record", "-i", "nosuchbus", "-c", "x", "--stats", tmp_path / "s.json"], "unknown python-can interface"),
        (["replay", rec, "--to-log", tmp_path / "x.log", "--speed", "0"], "argument --speed: invalid number > 0"),
        (["replay", rec, "--to-log", tmp_path / "x.log", "--speed", "inf"], "argument --speed"),
        (["replay", rec, "--to-log", tmp_path / "x.log", "--start", "2", "--stop", "1"], "--stop 1 must be after"),
        (["record", "--from-log", files / "in.log", "--count", "-1", "--stats", tmp_path / "s.json"], "--count"),
        (["record", "--from-log", files / "in.log"], "nothing to write"),
        (["eval", rec, "--bogus"], "unrecognized arguments: --bogus"),
        (["sim", tmp_path / "x.txt"], "unknown recording format '.txt'"),
        # a recording is built in memory: its size is bounded before any work
        (["sim", tmp_path / "x.csv", "--duration", "1e9"],
         "--duration 1e+09 s at --rate 100 Hz is 1e+11 samples: at most 10,000,000 in one recording"),
        (["sim", tmp_path / "x.csv", "--rate", "1e12"], "--rate 1e+12 Hz", "at most 10,000,000"),
        (["sim", tmp_path / "x.csv", "--lin-acc", "1", "--disturbance-every", "1e-9",
          "--disturbance-length", "1e-9"], "--duration / --disturbance-every", "at most 100,000"),
        (["sim", tmp_path / "x.csv", "--rest", "70"], "--rest must be shorter than --duration"),
        (["sim", tmp_path / "x.csv", "--seed", "-1"], "--seed must be an integer >= 0"),
        (["sim", tmp_path / "x.csv", "--pause-probability", "2"], "--pause-probability must be in 0..1"),
        (["replay", rec, "-i", "socketcan"], "-i socketcan needs -c/--channel"),
        (["record", "-i", "socketcan", "--stats", tmp_path / "s.json"], "-i socketcan needs -c/--channel"),
    ]
    for argv, *fragments in cases:
        check(capsys, argv, 2, *fragments, workdir=tmp_path)


def test_hdf5_of_the_wrong_kind(tmp_path, capsys):
    import h5py
    with h5py.File(tmp_path / "s.hdf5", "w") as fh:
        fh.create_dataset("imu_gyr", data=np.array([[b"ab", b"cd", b"ef"]] * 5))
        fh.create_dataset("imu_acc", data=np.zeros((5, 3)))
        fh.attrs["sampling_rate"] = 100.0
    check(capsys, ["eval", tmp_path / "s.hdf5"], 1, "s.hdf5: dataset 'imu_gyr': values of type |S2")
    (tmp_path / "cut.hdf5").write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(100))
    check(capsys, ["eval", tmp_path / "cut.hdf5"], 1, "cut.hdf5: cannot read as HDF5")


def test_bench_trial_selection_and_data(tmp_path, capsys):
    assert attekf(["sim", "-q", str(tmp_path / "t1.hdf5"), "--duration", "5"]) == 0
    check(capsys, ["bench", "--data", tmp_path, "--trials", "99", "--methods", "ours-9d"], 2,
          "--trials 99: no trial of")
    check(capsys, ["bench", "--data", tmp_path / "none", "--methods", "ours-9d"], 1, "none: no such directory")


def test_empty_log_replay_and_record_agree(tmp_path, capsys):
    (tmp_path / "empty.log").write_text("")
    for argv in (["replay", tmp_path / "empty.log", "--to-log", tmp_path / "x.log"],
                 ["record", "--from-log", tmp_path / "empty.log", "--stats", tmp_path / "s.json"]):
        check(capsys, argv, 1, "empty.log: no CAN data frames", workdir=tmp_path)


def test_console_script_one_line_no_traceback(files, tmp_path):
    """The installed command as a user runs it: the same line and status as in process."""
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    for argv, code, fragment in (
            (["eval", str(files / "rec.csv"), "--set", "accel_noise=abc"], 2, "is not a number"),
            (["replay", str(files / "rec.csv"), "--to-log", str(blocker / "x.log")], 1, "is not a directory"),
            (["record", "--from-log", str(tmp_path / "none.blf"), "--stats", str(tmp_path / "s.json")], 1,
             "no such file")):
        p = subprocess.run([str(ATTEKF), *argv], capture_output=True, text=True, timeout=60)
        assert p.returncode == code, (argv, p.stderr)
        lines = p.stderr.strip().splitlines()
        assert len(lines) == 1 and fragment in lines[0] and "Traceback" not in p.stderr, p.stderr
    assert sorted(os.listdir(tmp_path)) == ["afile"]


def test_internal_errors_are_one_line(monkeypatch, files, capsys):
    """A defect of the tools still ends as one line (ATTEKF_TRACEBACK=1 would raise)."""
    from attekf.commands import replay

    def broken(*_a, **_k):
        raise RuntimeError("something\nunexpected")
    monkeypatch.setattr(replay, "load_frames", broken)
    monkeypatch.delenv("ATTEKF_TRACEBACK", raising=False)
    check(capsys, ["replay", files / "rec.csv", "--to-log", files / "never.log"], 1,
          "internal error RuntimeError: something unexpected")
    assert not (files / "never.log").exists()


def test_log_format_python_can_cannot_write_here(files, tmp_path, capsys):
    """A log format python-can lists but cannot write without an optional package (.mf4 needs
    asammdf): a usage error before any work, for replay --to-log and record -o alike."""
    import importlib.util
    if importlib.util.find_spec("asammdf") is not None:
        pytest.skip("asammdf is installed: python-can writes .mf4 here")
    check(capsys, ["replay", files / "rec.csv", "--to-log", tmp_path / "x.mf4"], 2,
          "x.mf4: --to-log: python-can cannot write '.mf4' logs here", "asammdf", workdir=tmp_path)
    check(capsys, ["record", "--from-log", files / "in.log", "-o", tmp_path / "x.mf4"], 2,
          "x.mf4: -o: python-can cannot write '.mf4' logs here", workdir=tmp_path)
