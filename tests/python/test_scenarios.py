"""attekf.scenarios and `attekf sim --scenario`: every scenario's truth, sensors and events,
checked with independent formulations (exact integration of the gyro, the geometry of the
flip) and through the command."""

from __future__ import annotations

import json

import numpy as np
import pytest

from attekf import metrics as M
from attekf import scenarios as S
from attekf.cli import main
from attekf.io import read_recording

QUIET = dict(gyro_noise_density=0.0, gyro_bias_rad_s=0.0, acc_noise_density=0.0, mag_noise_density=0.0)


def integrate(rec):
    """The gyro integrated as body rotations over each sample's own time step (the
    estimator's convention), from the first truth sample."""
    q = np.empty((len(rec), 4))
    q[0] = rec.quat_ref[0]
    for k in range(1, len(rec)):
        q[k] = M.quat_normalize(M.quat_mul(q[k - 1], M.quat_from_rotvec(rec.gyr[k] * (rec.t[k] - rec.t[k - 1]))))
    return q


def angle_deg(a, b):
    return np.degrees(M.total_error(M.error_quat_earth(a, b)))


@pytest.mark.parametrize("name", ["flip", "tumble", "rotation", "gap", "clipping", "drops"])
def test_noise_free_gyro_integrates_to_the_truth(name):
    """Also across a gap and dropped samples: the gyro after them is the mean rate over the
    whole interval, so the rotation is kept (measured: within 3e-6 deg, the arccos limit)."""
    rec = S.build(S.ScenarioConfig.preset(name, rate_hz=100.0, seed=2, **QUIET))
    assert angle_deg(integrate(rec), rec.quat_ref).max() < 1e-4


def test_flip_geometry():
    """360 deg about body y; body x passes `approach` deg from the vertical (pitch 90 - approach);
    the peak rate and duration as asked; the events and the scored part."""
    cfg = S.ScenarioConfig.preset("flip", rate_hz=1000.0, peak_rate_deg_s=360.0, approach_deg=3.0, seed=4, **QUIET)
    rec = S.build(cfg)
    (kind, t0, t1), = S.events(rec)
    assert kind == "flip" and t0 == cfg.rest_s and t1 - t0 == pytest.approx(2.0)
    pitch = np.degrees(M.quat_to_euler(rec.quat_ref)[:, 1])
    assert np.abs(pitch).max() == pytest.approx(87.0, abs=0.01)
    rate = np.degrees(np.linalg.norm(rec.gyr, axis=1))
    assert rate.max() == pytest.approx(360.0, abs=0.5)
    body_y = np.abs(rec.gyr[(rec.t > t0) & (rec.t < t1)])
    assert (body_y[:, 0] < 1e-9).all() and (body_y[:, 2] < 1e-9).all()
    assert angle_deg(rec.quat_ref[:1], rec.quat_ref[-1:])[0] < 1e-6      # a full turn: back where it began
    np.testing.assert_array_equal(rec.movement, rec.t >= cfg.rest_s)


def test_glitch_integral_and_the_body_at_rest():
    cfg = S.ScenarioConfig.preset("glitch", rate_hz=100.0, glitch_deg=60.0, axis=(1.0, 0.0, 0.0), seed=1, **QUIET)
    rec = S.build(cfg)
    assert angle_deg(rec.quat_ref[:1], rec.quat_ref).max() == 0.0           # the truth does not move
    (kind, a, b), = S.events(rec)
    sel = (rec.t > a) & (rec.t <= b)
    assert sel.sum() == 3                                                    # 60 deg at <= 2000 deg/s, 100 Hz
    np.testing.assert_allclose(np.degrees(rec.gyr[sel].sum(axis=0) * 0.01), [60.0, 0.0, 0.0], atol=1e-9)
    assert np.abs(rec.gyr[~sel]).max() == 0.0


def test_gap_removes_its_samples():
    cfg = S.ScenarioConfig.preset("gap", rate_hz=100.0, seed=1, **QUIET)
    rec = S.build(cfg)
    _, before, after = S.events(rec, "gap")[0]
    dt = np.diff(rec.t)
    assert dt.max() == pytest.approx(after - before) and after - before == pytest.approx(0.31)
    assert np.sum(dt > 0.011) == 1 and rec.rate_hz == 100.0
    rot = S.events(rec, "rotation")[0]
    assert rot[1] < before < after < rot[2]


def test_modifiers_clip_offset_and_drops():
    run = S.build(S.ScenarioConfig.preset("clipping", rate_hz=100.0, seed=1))
    assert np.abs(run.acc).max() == pytest.approx(2 * 9.81)
    assert int(json.loads(run.meta["clipped_samples"])) > 100
    quiet = S.build(S.ScenarioConfig.preset("clipping", rate_hz=100.0, seed=1, clip_g=0.0))
    assert np.abs(quiet.acc).max() > 2.5 * 9.81                              # the impacts go beyond 2 g
    off = S.build(S.ScenarioConfig.preset("offset", rate_hz=100.0, seed=1, offset_deg_s=2.0,
                                          offset_drift_deg_s_per_min=1.0, **QUIET))
    true = S.build(S.ScenarioConfig.preset("offset", rate_hz=100.0, seed=1, offset_deg_s=0.0, **QUIET))
    extra = np.degrees(np.linalg.norm(off.gyr - true.gyr, axis=1))
    assert extra[0] == pytest.approx(2.0) and extra[-1] == pytest.approx(4.0)   # 2 + 1 deg/s per min x 2 min
    drops = S.build(S.ScenarioConfig.preset("drops", rate_hz=100.0, seed=1))
    assert len(drops) == 6001 - round(0.05 * 5999)


def test_noise_is_a_density():
    """The same sensor at 100 and 400 Hz: per-sample sigma doubles (x sqrt(4))."""
    sig = [S.build(S.ScenarioConfig.preset("glitch", rate_hz=r, gyro_bias_rad_s=0.0, glitch_deg=1.0, seed=3)).gyr[
        :500].std() for r in (100.0, 400.0)]
    assert sig[1] / sig[0] == pytest.approx(2.0, rel=0.1)


def test_same_seed_same_recording():
    a = S.build(S.ScenarioConfig.preset("tumble", seed=5))
    b = S.build(S.ScenarioConfig.preset("tumble", seed=5))
    c = S.build(S.ScenarioConfig.preset("tumble", seed=6))
    np.testing.assert_array_equal(a.gyr, b.gyr)
    assert not np.array_equal(a.quat_ref, c.quat_ref)


def test_config_is_checked():
    for bad in (dict(rate_hz=0.0), dict(peak_rate_deg_s=9000.0, rate_hz=100.0), dict(approach_deg=95.0),
                dict(count=0), dict(drop=1.0), dict(clip_g=0.5), dict(axis=(0.0, 0.0, 0.0))):
        with pytest.raises(ValueError):
            S.build(S.ScenarioConfig.preset("flip", **bad))
    with pytest.raises(ValueError, match="unknown scenario"):
        S.ScenarioConfig.preset("loop")


def test_sim_command_writes_a_scenario(tmp_path, capsys):
    out = tmp_path / "gap.hdf5"
    assert main(["sim", str(out), "--scenario", "gap", "--rate", "50", "--gap", "0.5", "--seed", "2"]) == 0
    assert "gap" in capsys.readouterr().out
    rec = read_recording(str(out))
    assert rec.rate_hz == 50.0 and np.diff(rec.t).max() == pytest.approx(0.52)   # per-sample times kept
    assert [e[0] for e in S.events(rec)] == ["rotation", "gap"]
    csv = tmp_path / "flip.csv"
    assert main(["sim", str(csv), "--scenario", "flip", "--approach", "2", "--peak-rate", "360", "-q"]) == 0
    assert read_recording(str(csv)).quat_ref is not None


@pytest.mark.parametrize("args, message", [
    (["--scenario", "flip", "--duration", "5"], "--duration does not apply to --scenario flip"),
    (["--scenario", "tumble", "--approach", "3"], "--approach does not apply"),
    (["--approach", "3"], "add --scenario"),
    (["--scenario", "flip", "--lin-acc", "2"], "random motion"),
    (["--scenario", "flip", "--peak-rate", "10000"], "--peak-rate turns 90 deg"),
    (["--scenario", "rotation", "--rate", "-5"], "--rate must be > 0"),
])
def test_sim_command_refuses_what_a_scenario_does_not_use(tmp_path, capsys, args, message):
    out = tmp_path / "x.hdf5"
    assert main(["sim", str(out), *args]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()
