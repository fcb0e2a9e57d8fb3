"""Sustained attitude near +-90 deg pitch (beyond gimbal_limit), simulated: the reported 3-sigma
covers the error of every angle. Beyond the limit the covariance is propagated at the clamped
pitch, so the reported roll and heading rows are scaled by cos(limit)/|cos(theta)|
(att_outputs.c; docs/derivation.md, "Gimbal lock"); without that scale the roll is over-confident
while the body wobbles about the vertical."""

from __future__ import annotations

import numpy as np
import pytest

from attekf import consistency as C
from attekf import native
from attekf import scenarios as S
from attekf.metrics import euler_to_quat

REST_S = 5.0


def near_vertical(pitch_deg: float, wobble_deg: float = 2.0, hold_s: float = 30.0, seed: int = 1):
    """Rest, pitch up to pitch_deg, wobble about body x and z there for hold_s, back, rest."""
    cfg = S.ScenarioConfig.preset("glitch", rate_hz=100.0, seed=seed, rest_s=REST_S)
    rng = np.random.default_rng(seed)
    chain = S.Chain(euler_to_quat(np.array([0.0, 0.0, np.radians(30.0)])))
    chain.rest(REST_S)
    chain.rotate([0.0, 1.0, 0.0], np.radians(pitch_deg), 3.0)
    for k in range(int(hold_s)):
        sign = 1.0 if k % 2 == 0 else -1.0
        chain.rotate([1.0, 0.0, 0.0], sign * np.radians(wobble_deg), 0.5)
        chain.rotate([0.0, 0.0, 1.0], sign * np.radians(wobble_deg), 0.5)
    chain.rotate([0.0, 1.0, 0.0], -np.radians(pitch_deg), 3.0)
    chain.rest(10.0)
    return S._from_motion(cfg, rng, chain.t, chain.attitude)


@pytest.mark.parametrize("pitch_deg, wobble_deg", [(88.5, 2.0), (89.5, 0.5), (89.9, 0.5)])
def test_reported_sigma_covers_a_sustained_near_vertical_attitude(pitch_deg, wobble_deg):
    """Within the limit, and beyond it (89.5, 89.9 with the default limit of 89 deg). Not yet
    covered: a body that wanders in and out of the clamp zone for tens of seconds (docs/derivation.md,
    "Gimbal lock")."""
    rec = near_vertical(pitch_deg, wobble_deg)
    for six_d in (False, True):
        r = native.run_arrays(rec.t, rec.gyr, rec.acc, None if six_d else rec.mag)
        cons = C.flat(C.consistency(r.quat, rec.quat_ref, angle_cov=r.angle_cov, movement=rec.movement,
                                    six_d=six_d))
        angles = ("roll", "pitch") if six_d else ("roll", "pitch", "yaw")
        cover = {a: cons[f"cov_{a}"] for a in angles}
        assert all(v >= 97.0 for v in cover.values()), (pitch_deg, "6D" if six_d else "9D", cover)
