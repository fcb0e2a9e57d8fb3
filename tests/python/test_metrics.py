"""attekf.metrics against hand-computed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from attekf import metrics as m


def qx(deg):
    a = math.radians(deg) / 2
    return np.array([math.cos(a), math.sin(a), 0.0, 0.0])


def qz(deg):
    a = math.radians(deg) / 2
    return np.array([math.cos(a), 0.0, 0.0, math.sin(a)])


REF = m.euler_to_quat(np.array([0.3, -0.4, 2.0]))  # an arbitrary truth attitude


def errs_deg(q_est, q_ref):
    e = m.error_quat_earth(q_est[None], q_ref[None])
    return [float(np.degrees(f(e))[0]) for f in (m.total_error, m.heading_error, m.inclination_error)]


def test_identical_is_zero_and_sign_does_not_matter():
    assert errs_deg(REF, REF) == pytest.approx([0, 0, 0], abs=1e-6)
    assert errs_deg(-REF, REF) == pytest.approx([0, 0, 0], abs=1e-6)


def test_pure_heading_and_pure_inclination_errors():
    # an error about earth z is all heading; about earth x all inclination
    assert errs_deg(m.quat_mul(qz(10), REF), REF) == pytest.approx([10, 10, 0], abs=1e-9)
    assert errs_deg(m.quat_mul(qx(7), REF), REF) == pytest.approx([7, 0, 7], abs=1e-9)


def test_combined_error_hand_computed():
    # e = qz(a) qx(b): e_w = cos(a/2) cos(b/2), e_z = sin(a/2) cos(b/2), so heading = a,
    # inclination = b and total = 2 acos(cos(a/2) cos(b/2)).
    a, b = 20.0, 30.0
    total = math.degrees(2 * math.acos(math.cos(math.radians(a / 2)) * math.cos(math.radians(b / 2))))
    got = errs_deg(m.quat_mul(m.quat_mul(qz(a), qx(b)), REF), REF)
    assert got == pytest.approx([total, a, b], abs=1e-9)
    assert total == pytest.approx(35.93, abs=0.01)  # cos10 cos15 = 0.95125


def test_heading_error_of_half_turn_is_pi_without_division_by_zero():
    e = np.array([[0.0, 0.0, 0.0, 1.0]])
    assert m.heading_error(e)[0] == pytest.approx(math.pi)
    assert m.total_error(e)[0] == pytest.approx(math.pi)


def test_rmse_mask_and_nan():
    x = np.array([3.0, 4.0, np.nan, 100.0])
    assert m.rmse(x, np.array([True, True, True, False])) == pytest.approx(math.sqrt(12.5))
    assert math.isnan(m.rmse(np.array([np.nan])))


def test_orientation_errors_scoring_mask():
    n = 5
    ref = np.tile(REF, (n, 1))
    est = np.tile(m.quat_mul(qz(2), REF), (n, 1))
    ref[1] = np.nan          # no truth
    est[2] = np.nan          # no estimate
    movement = np.array([True, True, True, True, False])
    e = m.orientation_errors(est, ref, movement)
    assert e.scored.tolist() == [True, False, False, True, False]
    assert e.rmse_deg() == pytest.approx({"total": 2.0, "heading": 2.0, "inclination": 0.0}, abs=1e-9)


def test_six_d_removes_constant_heading_offset_only():
    rng = np.random.default_rng(1)
    n = 200
    ref = m.quat_normalize(rng.normal(size=(n, 4)))
    tilt = m.quat_from_rotvec(np.column_stack([np.full(n, math.radians(1.0)), np.zeros(n), np.zeros(n)]))
    est = m.quat_mul(qz(30), m.quat_mul(tilt, ref))   # 30 deg heading offset + 1 deg tilt error
    nine = m.orientation_errors(est, ref)
    six = m.orientation_errors(est, ref, six_d=True)
    assert nine.rmse_deg()["heading"] == pytest.approx(30.0, abs=0.1)
    assert math.degrees(six.heading_offset_rad) == pytest.approx(30.0, abs=1e-6)
    assert six.rmse_deg()["heading"] == pytest.approx(0.0, abs=1e-6)
    assert six.rmse_deg()["inclination"] == pytest.approx(1.0, abs=1e-6)
    # circular mean: offsets of +179 and -179 deg average to 180, not 0
    ref2 = np.tile(REF, (2, 1))
    est2 = np.stack([m.quat_mul(qz(179), REF), m.quat_mul(qz(-179), REF)])
    assert abs(math.degrees(m.heading_offset(est2, ref2))) == pytest.approx(180.0, abs=1e-6)


def test_euler_convention_zyx_body_to_enu():
    # yaw 90 deg turns body x (east at yaw 0) to north (ENU y)
    q = m.euler_to_quat(np.array([0.0, 0.0, math.pi / 2]))
    np.testing.assert_allclose(m.quat_rotate(q, np.array([1.0, 0, 0])), [0, 1, 0], atol=1e-12)
    # positive pitch is a right-handed turn about body y: body x (the nose) goes down, towards -z
    q = m.euler_to_quat(np.array([0.0, math.radians(30), 0.0]))
    np.testing.assert_allclose(m.quat_rotate(q, np.array([1.0, 0, 0])),
                               [math.cos(math.radians(30)), 0, -math.sin(math.radians(30))], atol=1e-12)
    # q = qz(yaw) qy(pitch) qx(roll)
    e = np.array([0.2, -0.3, 1.1])
    qy = np.array([math.cos(e[1] / 2), 0, math.sin(e[1] / 2), 0])
    expect = m.quat_mul(m.quat_mul(m.quat_about_z(e[2]), qy), np.array([math.cos(e[0] / 2), math.sin(e[0] / 2), 0, 0]))
    np.testing.assert_allclose(m.euler_to_quat(e), expect, atol=1e-15)


def test_euler_round_trip():
    rng = np.random.default_rng(2)
    e = np.column_stack([rng.uniform(-3, 3, 100), rng.uniform(-1.5, 1.5, 100), rng.uniform(-3, 3, 100)])
    np.testing.assert_allclose(m.quat_to_euler(m.euler_to_quat(e)), e, atol=1e-9)


def test_rotvec():
    np.testing.assert_allclose(m.quat_from_rotvec(np.array([0, 0, math.radians(10)])), qz(10), atol=1e-15)
    np.testing.assert_allclose(m.quat_from_rotvec(np.zeros(3)), [1, 0, 0, 0])
