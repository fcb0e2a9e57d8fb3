"""The Python filter API (attekf.Filter, attekf.estimate; host_tools/attekf/filter.py): the
same filter as the C loop bit for bit, its time inputs, its errors, and the completeness of
what it exports (flags, diagnostics)."""

from __future__ import annotations

import pydoc
import re
import subprocess

import numpy as np
import pytest

import attekf
from attekf import native


def _c_vectors(scalar: str, tmp_path):
    """Inputs and outputs of attekf_vectors_<f|d|x>: att_step in a C loop (test_native.py)."""
    exe = native.build_dir() / f"attekf_vectors_{native.SCALARS[scalar]}"
    out = tmp_path / f"vectors_{scalar}.txt"
    subprocess.run([str(exe), str(out)], check=True, timeout=60)
    rows = [line.split("|") for line in out.read_text().splitlines()[2:]]
    inp = np.array([[float.fromhex(v) for v in left.split()] for left, _ in rows])
    outp = [right.split() for _, right in rows]
    quat = np.array([[float.fromhex(v) for v in r[18:22]] for r in outp])
    flags = np.array([int(r[22]) for r in outp])
    return inp, quat, flags


@pytest.mark.parametrize("scalar", ["float", "double", "fixed"])
def test_update_per_sample_is_the_c_loop_bit_for_bit(scalar, tmp_path):
    inp, quat, flags = _c_vectors(scalar, tmp_path)
    dt, gyr, acc, mag = inp[:, 1], inp[:, 2:5], inp[:, 5:8], inp[:, 8:11]
    f = attekf.Filter(scalar=scalar)
    got_q, got_flags = [], []
    for k in range(len(dt)):
        m = None if np.isnan(mag[k]).all() else mag[k]   # absent magnetometer rows
        est = f.update(gyr[k], acc[k], m, dt=dt[k])
        got_q.append(est.quaternion)
        got_flags.append(int(est.flags))
    got_q, got_flags = np.array(got_q), np.array(got_flags)
    np.testing.assert_array_equal(got_flags, flags)
    aligned = (flags & int(attekf.Flag.ALIGNED)) != 0
    np.testing.assert_array_equal(got_q[aligned], quat[aligned])
    assert np.isnan(got_q[~aligned]).all() and (~aligned).sum() == 9   # no estimate yet
    assert f.diag["rejected"] >= 3 and f.scalar == scalar   # (the vectors refuse 3 samples; 900 is clipped)


def test_batch_is_one_filter_with_the_per_sample_api(sim_recording):
    rec = sim_recording
    n = len(rec.t)
    res = attekf.estimate(rec.gyr, rec.acc, rec.mag, t=rec.t)
    # two batches on one Filter continue exactly (the second's first step from the timestamps)
    f = attekf.Filter()
    a = f.update_batch(rec.gyr[:700], rec.acc[:700], rec.mag[:700], t=rec.t[:700])
    b = f.update_batch(rec.gyr[700:], rec.acc[700:], rec.mag[700:], t=rec.t[700:])
    np.testing.assert_array_equal(np.vstack([a.quat, b.quat]), res.quat)
    assert b.diag == res.diag
    # per sample with the same time steps
    dt = np.diff(rec.t)
    dt = np.concatenate((dt[:1], dt))
    g = attekf.Filter()
    q = np.array([g.update(*s, dt=d).quaternion for s, d in zip(zip(rec.gyr, rec.acc, rec.mag), dt)])
    np.testing.assert_array_equal(q, res.quat)
    # and the binding's recording runner
    np.testing.assert_array_equal(native.run_estimator(rec).quat, res.quat)
    assert res.euler.shape == (n, 3) and res.sigma_euler.shape == (n, 3) and res.rate.shape == (n, 3)
    np.testing.assert_array_equal(res.sigma_euler, np.sqrt(res.var[:, 3:6]))


def test_time_from_a_rate_or_steps():
    rng = np.random.default_rng(1)
    n = 300
    gyr = rng.normal(0, 0.01, (n, 3))
    acc = np.tile([0.0, 0.0, 9.81], (n, 1)) + rng.normal(0, 0.05, (n, 3))
    by_rate = attekf.estimate(gyr, acc, rate_hz=200.0)
    by_dt = attekf.estimate(gyr, acc, dt=0.005)
    by_steps = attekf.estimate(gyr, acc, dt=np.full(n, 0.005))
    np.testing.assert_array_equal(by_rate.quat, by_dt.quat)
    np.testing.assert_array_equal(by_rate.quat, by_steps.quat)
    np.testing.assert_array_equal(by_rate.t, np.arange(n) / 200.0)
    assert by_rate.mag_absent == n
    fixed_rate = attekf.Filter(dt=0.005)      # like VQF(Ts): update() without dt
    q = np.array([fixed_rate.update(g, a).quaternion for g, a in zip(gyr, acc)])
    np.testing.assert_array_equal(q, by_rate.quat)


def test_estimate_fields_and_units():
    f = attekf.Filter({"align_samples": 5})
    est = None
    for _ in range(20):
        est = f.update([0.0, 0.0, 0.0], [0.0, 0.0, 9.81], [0.0, 20.0, -40.0], dt=0.01)
    assert est.aligned and est.status == "EKF_OK" and not est.refused
    assert est.flags & attekf.Flag.ALIGNED and isinstance(est, attekf.Estimate)
    assert est.covariance.shape == (3, 3) and est.gyro_bias.shape == (3,) and est.gyro_bias_sigma.shape == (3,)
    # level, body x pointing east (the field's horizontal part points north = body y)
    np.testing.assert_allclose(est.euler, [0.0, 0.0, 0.0], atol=1e-5)
    np.testing.assert_allclose(np.abs(est.quaternion), [1.0, 0.0, 0.0, 0.0], atol=1e-5)
    np.testing.assert_allclose(est.euler_deg, np.degrees(est.euler))
    assert (est.sigma > 0).all() and (est.sigma < 0.5).all()
    assert f.settings["align_samples"] == 5


def test_no_estimate_before_alignment():
    """Until the filter has aligned (align_samples accelerometer samples) the outputs say so:
    NaN attitude, infinite sigma and covariance diagonal; the sample after is an estimate."""
    f = attekf.Filter({"align_samples": 4}, dt=0.01)
    before = [f.update([0.0, 0.0, 0.0], [0.0, 0.0, 9.81], [0.0, 20.0, -40.0]) for _ in range(3)]
    for est in before:
        assert not est.aligned and est.status == "EKF_OK"
        assert np.isnan(est.quaternion).all() and np.isnan(est.euler).all() and np.isnan(est.rate).all()
        assert np.isposinf(est.sigma).all() and np.isposinf(np.diag(est.covariance)).all()
        assert est.covariance[0, 1] == 0.0
    est = f.update([0.0, 0.0, 0.0], [0.0, 0.0, 9.81], [0.0, 20.0, -40.0])
    assert est.aligned and np.isfinite(est.quaternion).all() and np.isfinite(est.sigma).all()
    res = attekf.estimate(np.zeros((20, 3)), np.tile([0.0, 0.0, 9.81], (20, 1)), rate_hz=100.0)
    assert np.isnan(res.quat[:9]).all() and np.isposinf(res.sigma_euler[:9]).all()
    assert np.isfinite(res.quat[9:]).all() and np.isfinite(res.sigma_euler[9:]).all()
    # after reset(), no estimate again
    f.reset()
    assert np.isnan(f.update([0.0, 0.0, 0.0], [0.0, 0.0, 9.81]).quaternion).all()


def test_a_nan_magnetometer_row_is_no_sample():
    """update(mag=[nan, nan, nan]) is update(mag=None), as a NaN row is in update_batch."""
    a, b = attekf.Filter(dt=0.01), attekf.Filter(dt=0.01)
    for _ in range(20):
        ea = a.update([0.01, 0.0, 0.0], [0.0, 0.0, 9.81], [np.nan] * 3)
        eb = b.update([0.01, 0.0, 0.0], [0.0, 0.0, 9.81])
    np.testing.assert_array_equal(ea.quaternion, eb.quaternion)
    assert a.diag == b.diag and a.diag["mag_fused"] == 0


def test_inputs_of_any_layout_and_type():
    """Rows of a strided or integer array, lists and tuples give the same sample."""
    base = attekf.Filter(dt=0.01)
    ref = [base.update([0.0, 0.0, 0.0], [0.0, 0.0, 9.0]).quaternion for _ in range(12)]
    wide = np.zeros((12, 6))
    wide[:, 2 * np.arange(3)] = [0.0, 0.0, 9.0]        # every other column: a strided view
    ints = np.array([[0, 0, 9]] * 12)
    for acc in (wide[:, ::2], ints, [(0, 0, 9)] * 12, np.asfortranarray(np.tile([0.0, 0.0, 9.0], (12, 1)))):
        f = attekf.Filter(dt=0.01)
        got = [f.update(np.zeros(3), a).quaternion for a in acc]
        np.testing.assert_array_equal(got, ref)
        f = attekf.Filter(dt=0.01)
        np.testing.assert_array_equal(f.update_batch(np.zeros((12, 3)), acc, dt=0.01).quat, ref)


def test_refused_sample_is_reported_and_counted():
    f = attekf.Filter(dt=0.01)
    for _ in range(12):
        f.update([0, 0, 0], [0, 0, 9.81])
    est = f.update([np.nan, 0.0, 0.0], [0.0, 0.0, 9.81])
    assert est.refused and est.status == "EKF_ERR_NOT_FINITE"
    assert f.diag["rejected"] == 1 and np.isfinite(est.quaternion).all()
    est = f.update([0, 0, 0], [0, 0, 9.81], dt=5.0)       # above dt_max (0.5 s)
    assert est.status == "EKF_ERR_DT_TOO_LARGE"


@pytest.mark.parametrize("call, error, fragment", [
    (lambda: attekf.Filter({"no_such": 1.0}), attekf.SettingsError, "unknown setting 'no_such'"),
    (lambda: attekf.Filter({"accel_noise": -1.0}), attekf.SettingsError, "accel_noise: -1.0 is not in [1e-09, 100]"),
    (lambda: attekf.Filter({"align_samples": 0.5}), attekf.SettingsError, "align_samples: 0.5 is not"),
    (lambda: attekf.Filter([("accel_noise", 1.0)]), TypeError, "settings: expected a mapping"),
    (lambda: attekf.Filter(dt=0), ValueError, "dt: 0 is not a positive, finite time step (s)"),
    (lambda: attekf.Filter(frame="NWU"), ValueError, "frame: 'NWU' is not one of ENU, NED"),
    (lambda: attekf.Filter(mounting=np.diag([1.0, 1.0, -1.0])), ValueError, "mounting: not a rotation"),
    (lambda: attekf.Filter(mounting=np.eye(2)), ValueError, "mounting: expected a finite 3x3"),
    (lambda: attekf.Filter(scalar="half"), ValueError, "scalar must be one of float, double, fixed"),
    (lambda: attekf.Filter().update([0, 0, 0], [0, 0, 9.81]), ValueError, "dt: give the time step"),
    (lambda: attekf.Filter().update([0, 0], [0, 0, 9.81], dt=0.01), ValueError, "gyr: expected three numbers (rad/s), got 2"),
    (lambda: attekf.Filter().update(0.1, [0, 0, 9.81], dt=0.01), TypeError, "gyr: 0.1 is not three numbers (rad/s)"),
    (lambda: attekf.Filter().update([0, 0, 0], [0, 0, 9.81], np.zeros((3, 2)), dt=0.01), TypeError, "mag: "),
    (lambda: attekf.Filter().update([0, 0, 0], "abc", dt=0.01), TypeError, "acc: 'abc' is not three numbers"),
    (lambda: attekf.Filter().update([0, 0, 0], [0, 0, 9.81], dt="x"), TypeError, "dt: 'x' is not a number"),
    (lambda: attekf.Filter().update([0, 0, 0], [0, 0, 9.81], dt=0.0), ValueError, "dt: 0.0 is not a positive, finite"),
    (lambda: attekf.Filter().update([0, 0, 0], [0, 0, 9.81], dt=-0.01), ValueError, "dt: -0.01 is not a positive"),
    (lambda: attekf.Filter().update([0, 0, 0], [0, 0, 9.81], dt=np.nan), ValueError, "dt: nan is not a positive"),
    (lambda: attekf.Filter().update([0, 0, 0], [0, 0, 9.81], dt=np.inf), ValueError, "dt: inf is not a positive"),
    (lambda: attekf.Filter().update([0, 0, 0], [0, 0, 9.81], 0.01), TypeError, "mag: 0.01 is not three numbers (uT)"),
    (lambda: attekf.Filter().update([0, 0, 0], [0, 0, 9.81], dt=0.01, gyr=[0, 0, 0]), TypeError, "multiple values for argument 'gyr'"),
    (lambda: attekf.Filter().update([0, 0, 0], [0, 0, 9.81], time=0.01), TypeError, "unexpected keyword argument 'time'"),
    (lambda: attekf.Filter().update([0, 0, 0]), TypeError, "missing 1 required positional argument: 'acc'"),
    (lambda: attekf.estimate(np.zeros((5, 3)), np.zeros((4, 3)), rate_hz=100), ValueError, "acc: shape (4, 3), expected (5, 3)"),
    (lambda: attekf.estimate(np.zeros((5, 3)), np.zeros((5, 3))), ValueError, "give t (timestamps, s), rate_hz (Hz) or dt (s)"),
    (lambda: attekf.estimate(np.zeros((5, 3)), np.zeros((5, 3)), rate_hz=100, dt=0.01), ValueError, "exactly one of"),
    (lambda: attekf.estimate(np.zeros((5, 3)), np.zeros((5, 3)), rate_hz=-1), ValueError, "rate_hz: -1 is not a positive"),
    (lambda: attekf.estimate(np.zeros(3), np.zeros((1, 3)), rate_hz=100), ValueError, "gyr: shape (3,), expected (N, 3)"),
    (lambda: attekf.estimate(np.zeros((5, 3)), np.zeros((5, 3)), rate_hz=0), ValueError, "rate_hz: 0 is not a positive"),
    (lambda: attekf.estimate(np.zeros((5, 3)), np.zeros((5, 3)), dt=0), ValueError, "dt: 0 is not a positive, finite"),
    (lambda: attekf.estimate(np.zeros((5, 3)), np.zeros((5, 3)), dt=-0.01), ValueError, "dt: -0.01 is not a positive"),
    (lambda: attekf.estimate(np.zeros((5, 3)), np.zeros((5, 3)), dt=np.nan), ValueError, "dt: nan is not a positive"),
    (lambda: attekf.estimate(np.zeros((5, 3)), np.zeros((5, 3)), dt=np.inf), ValueError, "dt: inf is not a positive"),
    (lambda: attekf.estimate(np.zeros((5, 3)), np.zeros((5, 3)), dt=[0.01, 0.01, 0.0, 0.01, 0.01]), ValueError,
     "dt: sample 2: 0.0 is not a positive"),
    (lambda: attekf.estimate(np.zeros((5, 3)), np.zeros((5, 3)), t=[0, 1, 1, 2, 3]), ValueError,
     "t: not strictly increasing: t[2] = 1.0 after t[1] = 1.0"),
    (lambda: attekf.estimate(np.zeros((5, 3)), np.zeros((5, 3)), t=[0, 1, np.nan, 2, 3]), ValueError,
     "t: sample 2: nan is not a finite time"),
    (lambda: attekf.estimate(np.zeros((3, 3)), np.zeros((3, 3)), rate_hz=100), ValueError, "gyr: shape (3, 3) is ambiguous"),
    (lambda: attekf.estimate(np.zeros((3, 50)), np.zeros((50, 3)), rate_hz=100), ValueError,
     "gyr: shape (3, 50), expected (N, 3): samples are rows (gyr.T?)"),
    (lambda: attekf.estimate(np.zeros((50, 3)), np.zeros((50, 4)), rate_hz=100), ValueError, "acc: shape (50, 4), expected (50, 3)"),
    (lambda: attekf.estimate(np.zeros((50, 3)), [["a", "b", "c"]] * 50, rate_hz=100), TypeError, "acc: not an array of numbers"),
    (lambda: attekf.estimate(np.zeros((50, 3)), np.zeros((50, 3)), rate_hz=100, with_6d=True), ValueError,
     "with_6d: without a magnetometer"),
    (lambda: attekf.Filter().update_batch(np.zeros((5, 3)), np.zeros((5, 3))), ValueError, "give t (timestamps, s)"),
])
def test_errors_name_the_argument(call, error, fragment):
    with pytest.raises(error) as err:
        call()
    assert fragment in str(err.value)


def test_reset_starts_again():
    f = attekf.Filter(dt=0.01)
    first = [f.update([0.01, 0, 0], [0, 0.1, 9.8]).quaternion for _ in range(30)]
    f.reset()
    again = [f.update([0.01, 0, 0], [0, 0.1, 9.8]).quaternion for _ in range(30)]
    np.testing.assert_array_equal(first, again)
    assert f.diag["steps"] == 20


def test_flags_are_every_att_flag(repo_root):
    text = (repo_root / "firmware" / "att" / "att.h").read_text()
    c_flags = {m.group(1): 1 << int(m.group(2))
               for m in re.finditer(r"#define ATT_FLAG_(\w+)\s+\(1u << (\d+)\)", text)}
    # every ATT_FLAG_ define is a single bit in that form, so none escapes the pattern above
    assert len(c_flags) == len(re.findall(r"#define ATT_FLAG_\w+", text)), "an ATT_FLAG_ the pattern missed"
    assert c_flags and {f.name: int(f) for f in attekf.Flag} == c_flags
    assert native.ATT_FLAGS == c_flags


def test_status_codes_match_ekf_h(repo_root):
    text = (repo_root / "firmware" / "ekf" / "ekf.h").read_text()
    c_codes = {m.group(1): int(m.group(2)) for m in re.finditer(r"\b(EKF_[A-Z_]+) = (\d+),?\s", text)}
    assert "EKF_SKIPPED" in c_codes
    for name in ("EKF_OK", "EKF_ERR_NOT_INITIALISED", "EKF_GATED", "EKF_SKIPPED"):
        assert getattr(native, name) == c_codes[name], name


@pytest.mark.parametrize("scalar", ["float", "double", "fixed"])
def test_every_diagnostic_is_exported(scalar, repo_root):
    lib = native.load(scalar)
    assert lib.tables_complete()
    text = (repo_root / "firmware" / "att" / "att.h").read_text()
    body = text[:text.index("} att_diag_t;")].rsplit("typedef struct {", 1)[1]
    counters = re.findall(r"uint32_t\s+(\w+);", body)
    values = re.findall(r"ekf_scalar_t\s+(\w+)", body)
    assert lib.diag_names == counters
    assert lib.diag_value_names == values
    f = attekf.Filter(scalar=scalar)
    assert set(f.diag) == set(counters) and set(f.diag_values) == set(values)
    assert len(f.diag_values["gyro_ratio"]) == 3 and isinstance(f.diag_values["mag_ratio"], float)


def test_help_explains_units():
    for obj, words in ((attekf.Filter, ("rad/s", "m/s^2", "uT", " s", "SettingsError", "NED", "mounting",
                                        "get_state")),
                       (attekf.Estimate, ("rad", "ENU", "[w, x, y, z]", "refused", "NaN", "gyro_bias")),
                       (attekf.estimate, ("(N, 3)", "rad/s", "Hz", "one C call", "with_6d")),
                       (attekf.filter, ("roll, pitch, yaw", "ZYX", "x east", "1-sigma", "NaN", "infinite")),
                       (attekf.Result, ("rad^2", "body->ENU", "NaN"))):
        doc = pydoc.render_doc(obj, renderer=pydoc.plaintext)
        for w in words:
            assert w in doc, f"help({obj.__name__}) does not mention {w!r}"
    info = attekf.setting_info()
    assert info["accel_noise"]["unit"] == "m/s^2*sqrt(s)" and "default" in info["gyro_noise"]
    assert attekf.default_settings("double")["align_samples"] == 10


def test_a_batch_lets_other_threads_run_and_guards_its_filter():
    """The batch runner releases the GIL (other threads run meanwhile) and marks its filter
    busy: using that filter from another thread then is a RuntimeError, not a data race."""
    import threading
    n = 400_000
    rng = np.random.default_rng(3)
    gyr = rng.normal(0, 0.1, (n, 3))
    acc = np.tile([0.0, 0.0, 9.81], (n, 1)) + rng.normal(0, 0.1, (n, 3))
    dt = np.full(n, 0.005)
    f = attekf.Filter(dt=0.005)
    core = f._core
    th = threading.Thread(target=lambda: core.run(dt, gyr, acc, *[None] * 10))
    seen = []
    th.start()
    while th.is_alive() and not seen:
        try:
            f.diag                               # reads the filter: refused while the batch runs
        except RuntimeError as exc:
            seen.append(str(exc))
    th.join()
    assert seen == ["this filter is running a batch in another thread"]
    assert f.diag["steps"] == n - 10        # only the batch's samples went in (10 aligned it)

