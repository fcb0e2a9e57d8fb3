"""The shared pieces every command relies on: attekf.outputs (checked first, whole or absent),
attekf.errors (one line, location attributes, exit status), attekf.canlog (one strict reader
of CAN logs) and the error-to-status mapping of attekf.commands.run_command."""

from __future__ import annotations

import os

import pytest

from attekf import canlog
from attekf.commands import parse_pair, run_command
from attekf.errors import InputError, Interrupted, OutputError, UsageError
from attekf.outputs import Outputs, atomic_path, check_directory, check_file


def test_outputs_commit_renames_everything_together(tmp_path):
    with Outputs() as out:
        a = out.file(str(tmp_path / "new" / "a.txt"), "--a")
        b = out.file(str(tmp_path / "b.json"), "--b")
        with out.open(a) as fh:
            fh.write("A")
        with open(out.temp(b), "w") as fh:
            fh.write("B")
        assert not os.path.exists(a) and not os.path.exists(b)       # nothing final yet
        assert sorted(out.pending) == sorted([a, b])
        assert out.commit() == [a, b]
    assert open(a).read() == "A" and open(b).read() == "B"
    assert sorted(os.listdir(tmp_path)) == ["b.json", "new"]


def test_outputs_abort_restores_the_directory(tmp_path):
    (tmp_path / "keep.txt").write_text("old")
    with pytest.raises(RuntimeError):
        with Outputs() as out:
            k = out.file(str(tmp_path / "keep.txt"), "--k")
            d = out.file(str(tmp_path / "x" / "y" / "z.txt"), "--z")
            for p in (k, d):
                with out.open(p) as fh:
                    fh.write("new")
            raise RuntimeError("the work failed")
    assert sorted(os.listdir(tmp_path)) == ["keep.txt"] and (tmp_path / "keep.txt").read_text() == "old"


def test_outputs_refuse_duplicates_and_inputs(tmp_path):
    out = Outputs()
    out.inputs([str(tmp_path / "in.log")])
    with pytest.raises(UsageError, match="would overwrite the input"):
        out.file(str(tmp_path / "in.log"), "-o")
    out.file(str(tmp_path / "a.csv"), "--csv")
    with pytest.raises(UsageError, match=r"named twice as an output \(--csv and --inputs-csv\)"):
        out.file(str(tmp_path / "." / "a.csv"), "--inputs-csv")


def test_checks(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    assert check_file(str(tmp_path / "a" / "b" / "c.json"), "--json")      # dirs made later
    with pytest.raises(OutputError, match="is a directory"):
        check_file(str(tmp_path), "--json")
    with pytest.raises(OutputError, match=r"file is not a directory"):
        check_file(str(f / "c.json"), "--json")
    with pytest.raises(OutputError, match=r"exists and is not a directory \(--out"):
        check_directory(str(f), "--out")
    with pytest.raises(OutputError, match=r"/proc.*cannot write|cannot write.*/proc"):
        check_file("/proc/attekf-none/x.json", "--json")
    with pytest.raises(UsageError):
        check_file("", "--json")
    assert os.listdir(tmp_path) == ["file"]                                  # probes removed


def test_atomic_path(tmp_path):
    p = tmp_path / "d" / "f.txt"
    with atomic_path(str(p)) as tmp:
        assert os.path.basename(tmp).startswith(".partial-") and tmp.endswith("f.txt")
        open(tmp, "w").write("ok")
    assert p.read_text() == "ok"
    with pytest.raises(ValueError):
        with atomic_path(str(p)) as tmp:
            open(tmp, "w").write("half")
            raise ValueError
    assert p.read_text() == "ok" and os.listdir(p.parent) == ["f.txt"]


def test_input_error_location_and_one_line():
    e = InputError("empty cell", path="a.csv", line=3, field="t_s")
    assert str(e) == "a.csv: line 3: column t_s: empty cell" and (e.path, e.line, e.field) == ("a.csv", 3, "t_s")
    assert str(InputError("x.log: two\nlines")) == "x.log: two lines"
    assert InputError("x").exit_code == 1 and UsageError("x").exit_code == 2 and Interrupted("x").exit_code == 130


def test_run_command_maps_every_error(capsys):
    from attekf.native import NativeError, SettingsError

    def raising(exc):
        def body():
            raise exc
        return body
    for exc, code, text in ((UsageError("bad option"), 2, "error: bad option"),
                            (InputError("f.csv: line 2: bad"), 1, "error: f.csv: line 2: bad"),
                            (OutputError("o.json: cannot write"), 1, "error: o.json"),
                            (SettingsError("unknown setting 'x'"), 2, "unknown setting"),
                            (NativeError("library\nmissing"), 1, "library missing"),
                            (KeyboardInterrupt(), 130, "interrupted: nothing written"),
                            (Interrupted("after 3 of 9"), 130, "interrupted: after 3 of 9"),
                            (OSError(28, "No space left on device", "out.csv"), 1,
                             "error: out.csv: No space left on device"),
                            (ZeroDivisionError("boom"), 1, "internal error ZeroDivisionError: boom")):
        assert run_command("x", raising(exc)) == code
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("attekf x: ") and text in err, err


def test_parse_pair():
    assert parse_pair(" accel_noise = 0.3", "--set") == ("accel_noise", 0.3)
    for bad, text in (("x", "expected NAME=VALUE"), ("=1", "expected NAME=VALUE"), ("x=abc", "not a number"),
                      ("x=inf", "not a finite number")):
        with pytest.raises(UsageError, match=text):
            parse_pair(bad, "--set")


@pytest.mark.parametrize("line, kind", [
    ("(1436509052.249713) vcan0 123#DEADBEEF", "data"),
    ("(0.000000) can0 12345678#", "data"),
    ("(0.000000) vcan0 123#R", "remote"),
    ("(0.000000) vcan0 123##1DEADBEEF", "fd"),
    ("(0.000000) vcan0 20000004#0000000000000000", "error"),
    ("(0.000000) vcan0 123#00 R", "data"),
    ("  ", None),
    ("# a comment", None),
])
def test_candump_line_kinds(line, kind):
    r = canlog.parse_candump_line(line, "f.log: line 1")
    assert (r[0] if r else None) == kind


def test_candump_frame_values():
    kind, t, fid, data, ext = canlog.parse_candump_line("(12.500000) vcan0 1ABCDEF0#0102", "w")
    assert (t, fid, data, ext) == (12.5, 0x1ABCDEF0, b"\x01\x02", True)


def test_skipped_frames_are_counted(tmp_path):
    p = tmp_path / "mix.log"
    p.write_text("(0.0) vcan0 123#R\n(0.1) vcan0 123##100\n(0.2) vcan0 100#01\n")
    st = canlog.LogStats()
    assert list(canlog.read_frames(str(p), stats=st)) == [(0.2, 0x100, b"\x01", False)]
    assert (st.frames, st.remote_frames, st.fd_frames) == (1, 1, 1)
    p.write_text("(0.0) vcan0 123#R\n")
    with pytest.raises(InputError, match=r"no CAN data frames in the log \(only 1 remote frames\)"):
        list(canlog.read_frames(str(p)))


def test_stop_flag_ends_reading(tmp_path):
    p = tmp_path / "many.log"
    p.write_text("".join(f"({k}.000000) vcan0 100#00\n" for k in range(100)))
    stop = [False]
    got = 0
    for _ in canlog.read_frames(str(p), stop=stop):
        got += 1
        if got == 10:
            stop[0] = True
    assert got == 10
