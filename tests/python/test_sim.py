"""attekf.sim: determinism and physical consistency of the synthetic recordings."""

from __future__ import annotations

import json

import numpy as np
import pytest

from attekf import metrics as m
from attekf.cli import main
from attekf.io import read_recording
from attekf.sim import SimConfig, simulate, static_mask

QUIET = dict(gyro_noise_rad_s=0.0, gyro_bias_rad_s=0.0, acc_noise_m_s2=0.0, mag_noise_uT=0.0)


def test_deterministic_with_seed():
    a = simulate(SimConfig(duration_s=10, seed=5))
    b = simulate(SimConfig(duration_s=10, seed=5))
    c = simulate(SimConfig(duration_s=10, seed=6))
    for name in ("t", "gyr", "acc", "mag", "quat_ref", "movement"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert not np.array_equal(a.quat_ref, c.quat_ref)


def test_noise_free_gyro_integrates_to_the_truth():
    """Integrating the (noise-free) gyro reproduces the truth: the sensor and the truth agree."""
    rec = simulate(SimConfig(duration_s=20, seed=1, **QUIET))
    dt = 1.0 / rec.rate_hz
    q = rec.quat_ref[0].copy()
    worst = 0.0
    for k in range(1, len(rec)):
        q = m.quat_normalize(m.quat_mul(q, m.quat_from_rotvec(rec.gyr[k] * dt)))
        worst = max(worst, float(m.total_error(m.error_quat_earth(q[None], rec.quat_ref[k][None]))[0]))
    # exact within a rotation; the only error is at segment joins (rate ~0 there): tiny
    assert np.degrees(worst) < 1e-6


def test_accelerometer_and_magnetometer_follow_the_truth():
    rec = simulate(SimConfig(duration_s=20, seed=2, field_uT=48.0, dip_deg=65.0, **QUIET))
    up = m.quat_rotate(rec.quat_ref, rec.acc)          # body -> ENU
    np.testing.assert_allclose(up, np.tile([0, 0, 9.81], (len(rec), 1)), atol=1e-9)
    field = m.quat_rotate(rec.quat_ref, rec.mag)
    dip = np.radians(65.0)
    np.testing.assert_allclose(field, np.tile([0, 48 * np.cos(dip), -48 * np.sin(dip)], (len(rec), 1)),
                               atol=1e-9)


def test_tilt_bound_static_phases_and_movement():
    rec = simulate(SimConfig(duration_s=60, seed=4, max_tilt_deg=45))
    e = m.quat_to_euler(rec.quat_ref)
    assert np.degrees(np.abs(e[:, :2])).max() < 60  # targets within 45 deg; arcs stay close
    static = static_mask(rec)
    assert static[:300].all()                          # initial rest, 3 s at 100 Hz
    assert 0.1 < static[300:].mean() < 0.6            # static phases between rotations
    assert not rec.movement[:300].any() and rec.movement[300:].all()


def test_disturbance_episodes():
    cfg = SimConfig(duration_s=60, seed=7, lin_acc_m_s2=3.0, mag_disturbance_uT=30.0, **QUIET)
    rec = simulate(cfg)
    kinds = [k for k, _, _ in cfg.episodes]
    assert kinds.count("linear_acceleration") == 2 and kinds.count("magnetic_disturbance") == 2
    # extra specific force in the earth frame (horizontal: it hardly changes |acc|)
    acc_dev = np.linalg.norm(m.quat_rotate(rec.quat_ref, rec.acc) - [0, 0, 9.81], axis=1)
    mag_dev = np.abs(np.linalg.norm(rec.mag, axis=1) - 50.0)
    inside_acc = np.zeros(len(rec), bool)
    inside_mag = np.zeros(len(rec), bool)
    for kind, a, b in cfg.episodes:
        sel = (rec.t >= a) & (rec.t <= b)
        (inside_acc if kind == "linear_acceleration" else inside_mag)[sel] = True
    assert acc_dev[inside_acc].max() > 2.5 and acc_dev[~inside_acc].max() < 1e-9
    assert mag_dev[inside_mag].max() > 10.0 and mag_dev[~inside_mag].max() < 1e-9


def test_config_is_validated():
    with pytest.raises(ValueError, match="rate_hz must be > 0"):
        simulate(SimConfig(rate_hz=0))
    with pytest.raises(ValueError, match="initial_rest_s must be shorter"):
        simulate(SimConfig(duration_s=2, initial_rest_s=3))


def test_sim_command_writes_csv_and_hdf5(tmp_path, capsys):
    csv_path, h5_path = tmp_path / "a.csv", tmp_path / "a.hdf5"
    args = ["--duration", "5", "--seed", "9", "--lin-acc", "2"]
    assert main(["sim", str(csv_path), *args]) == 0
    assert "wrote" in capsys.readouterr().out
    assert main(["sim", "-q", str(h5_path), *args]) == 0
    assert capsys.readouterr().out == ""
    a, b = read_recording(str(csv_path)), read_recording(str(h5_path))
    assert len(a) == len(b) == 501
    np.testing.assert_allclose(a.gyr, b.gyr, rtol=1e-9, atol=1e-12)
    assert json.loads(b.meta["sim_config"])["seed"] == 9
    # same arguments, same bytes
    again = tmp_path / "b.csv"
    assert main(["sim", "-q", str(again), *args]) == 0
    assert again.read_bytes() == csv_path.read_bytes()
    # no magnetometer: no mag columns
    assert main(["sim", "-q", str(tmp_path / "nomag.csv"), "--duration", "5", "--no-mag"]) == 0
    assert read_recording(str(tmp_path / "nomag.csv")).mag is None


def test_sim_command_bad_arguments(tmp_path, capsys):
    assert main(["sim", str(tmp_path / "a.csv"), "--rate", "-1"]) == 2
    err = capsys.readouterr().err
    assert "rate_hz must be > 0" in err and err.count("\n") == 1
    assert main(["sim", str(tmp_path / "a.txt")]) == 2
    assert "unknown recording format" in capsys.readouterr().err
