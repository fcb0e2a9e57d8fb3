"""Corrupt CAN logs of every format `attekf replay` reads must give a one-line ReplayError
naming the file, never another exception (docs/reliability.md, "Findings"): python-can's
readers raise struct errors and the like on such input.

The fuzz target (tests/fuzz/fuzz_parsers.py, atheris) runs in scripts/fuzz.sh; these inputs
run in every pytest.
"""
import pytest

from attekf.commands import replay


@pytest.mark.parametrize("name,data", [
    ("short.blf", b";;"),                      # python-can's BLF reader: struct.error
    ("bad.blf", b"LOGG" + b"\x00" * 80),        # header present, objects garbage
    ("bad.asc", b"date Mon Jan 1\nbase hex timestamps absolute\n0.1 1 zz Rx d 8\n"),
    ("bad.log", b"(x) vcan0 123#GG\n"),
])
def test_corrupt_can_logs_raise_replay_error(tmp_path, name, data):
    path = tmp_path / name
    path.write_bytes(data)
    with pytest.raises(replay.ReplayError) as exc:
        replay.load_frames(str(path))
    msg = str(exc.value)
    assert str(path) in msg and "\n" not in msg
