"""The `attekf` command line: help, sim -> eval end to end, bad input, the main job."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from attekf.cli import build_parser, main


def _sim(path, *extra):
    assert main(["sim", "-q", str(path), "--duration", "12", *extra]) == 0


def test_every_command_has_help(capsys):
    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices  # argparse keeps them here
    assert {"sim", "eval"} <= set(commands)
    for name in commands:
        with pytest.raises(SystemExit) as exc:
            main([name, "--help"])
        assert exc.value.code == 0
        out = capsys.readouterr().out
        assert "--quiet" in out, name


def test_eval_directory_writes_table_json_and_plots(tmp_path, capsys):
    rec_dir = tmp_path / "recs"
    _sim(rec_dir / "one.csv", "--seed", "1")
    _sim(rec_dir / "two.hdf5", "--seed", "2", "--lin-acc", "3", "--mag-disturbance", "30")
    out = tmp_path / "out"
    assert main(["eval", "-q", str(rec_dir), "--out", str(out), "--save-output"]) == 0
    stdout = capsys.readouterr().out
    assert "one" in stdout and "two" in stdout and "mean of 2" in stdout
    assert (out / "table.txt").read_text().startswith("RMSE over the scored")
    data = json.loads((out / "results.json").read_text())
    assert [t["name"] for t in data["trials"]] == ["one", "two"]
    assert data["settings"]["align_samples"] == 10
    assert set(data["mean_rmse_deg"]) == {"total", "heading", "inclination"}
    for t in data["trials"]:
        assert t["counts"]["scored"] > 0 and t["counts"]["refused"] == 0
    for name in ("one", "two"):
        png = (out / f"{name}.png").read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 50_000
    # the saved output evaluates to the same numbers through --output-csv
    assert main(["eval", "-q", str(rec_dir / "one.csv"), "--output-csv", str(out / "one_output.csv"),
                 "--json", str(tmp_path / "again.json"), "--no-plot"]) == 0
    again = json.loads((tmp_path / "again.json").read_text())
    for k, v in data["trials"][0]["rmse_deg"].items():
        assert again["trials"][0]["rmse_deg"][k] == pytest.approx(v, abs=1e-6)


def test_eval_settings_and_scalar(tmp_path, capsys):
    _sim(tmp_path / "a.csv")
    assert main(["eval", "-q", str(tmp_path / "a.csv"), "--scalar", "double", "--set", "accel_noise=0.3",
                 "--json", str(tmp_path / "r.json")]) == 0
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["settings"]["accel_noise"] == 0.3 and data["estimator"] == "C estimator (double)"
    assert main(["eval", "--list-settings"]) == 0
    assert "mag_heading_noise" in capsys.readouterr().out


@pytest.mark.parametrize("argv, code, fragment", [
    (["eval", "{d}/missing.csv"], 1, "missing.csv: no such file"),
    (["eval", "{d}/bad.csv"], 1, "bad.csv: line 3: t_s"),
    (["eval", "{d}/a.csv", "--set", "nope=1"], 2, "unknown setting 'nope'"),
    (["eval", "{d}/a.csv", "--set", "accel_noise"], 2, "expected NAME=VALUE"),
    (["eval", "{d}/a.csv", "--set", "gimbal_limit=3"], 2, "gimbal_limit: 3.0 is not in [0.1, 1.56] (rad)"),
    (["eval", "{d}", "--output-csv", "{d}/a.csv"], 2, "--output-csv scores one recording, 2 given"),
    (["eval", "{d}/a.csv", "--output-csv", "{d}/a.csv"], 1, "missing column(s) roll_rad"),
    (["eval"], 2, "no recording given"),
    (["eval", "{d}/empty"], 1, "no recordings"),
])
def test_eval_bad_input_one_line_error(tmp_path, capsys, argv, code, fragment):
    _sim(tmp_path / "a.csv")
    (tmp_path / "bad.csv").write_text("t_s,gyr_x_rad_s,gyr_y_rad_s,gyr_z_rad_s,acc_x_m_s2,acc_y_m_s2,acc_z_m_s2\n"
                                      "1,0,0,0,0,0,9.8\n0.5,0,0,0,0,0,9.8\n")
    (tmp_path / "empty").mkdir()
    argv = [a.format(d=tmp_path) for a in argv]
    assert main(argv) == code
    err = capsys.readouterr().err
    assert fragment in err, err
    assert err.startswith("attekf eval: error: ") and err.count("\n") == 1


def test_eval_counts_refused_samples(tmp_path, capsys):
    """A sample the estimator refuses (gyro beyond its range) is counted in the table and JSON."""
    from attekf.io import read_recording, write_recording
    _sim(tmp_path / "a.csv")
    rec = read_recording(str(tmp_path / "a.csv"))
    rec.gyr[600, 0] = 45.0  # beyond gyro_range (40 rad/s), below the deg/s detection (70)
    write_recording(str(tmp_path / "b.csv"), rec)
    assert main(["eval", "-q", str(tmp_path / "b.csv"), "--json", str(tmp_path / "r.json")]) == 0
    out = capsys.readouterr().out
    assert "1 samples refused by the estimator" in out and "EKF_ERR_RANGE" in out
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["trials"][0]["counts"]["refused"] == 1


def test_console_script_runs():
    exe = os.path.join(os.path.dirname(sys.executable), "attekf")
    r = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.startswith("attekf ")


def test_demo_script(repo_root, tmp_path):
    """The main job (scripts/demo.sh) runs and writes its table and plots, and every path
    under out/demo/ that the docs or a command's help names is one it writes."""
    import re
    from attekf.cli import _command_modules
    r = subprocess.run([str(repo_root / "scripts" / "demo.sh"), str(tmp_path / "demo")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "mean of 2" in r.stdout
    for f in ("table.txt", "results.json", "undisturbed.png", "disturbed.png"):
        assert (tmp_path / "demo" / f).stat().st_size > 0, f
    texts = [(repo_root / "README.md").read_text()] + [p.read_text() for p in (repo_root / "docs").glob("*.md")]
    texts += [getattr(m, "DESCRIPTION", "") for m in _command_modules()]
    texts.append((repo_root / "scripts" / "demo.sh").read_text())
    named = {m for t in texts for m in re.findall(r"out/demo/[\w./-]*[\w]", t)}
    assert "out/demo/recordings/undisturbed.csv" in named
    for path in sorted(named):
        assert (tmp_path / "demo" / path[len("out/demo/"):]).exists(), f"documented but not written: {path}"
    # the simulator prints the disturbance episodes; the disturbed plot's recording declares them
    from attekf.io import read_recording
    from attekf.evaluate import recording_episodes
    eps = recording_episodes(read_recording(str(tmp_path / "demo" / "recordings" / "disturbed.csv")))
    assert len(eps) == 4
    for kind, a, b in eps:
        assert f"{kind.replace('_', ' ')} {a:.1f}-{b:.1f} s" in r.stdout
