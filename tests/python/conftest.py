"""Shared fixtures of the Python tests (host tools). Keep small: sub-folders add their own.
Missing data or tools skip outside CI and fail under CI=true (prereq.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

import prereq

REPO = prereq.REPO


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO


@pytest.fixture(scope="session")
def sim_recording():
    """A 20 s simulated recording with magnetometer and truth (session-wide; do not modify)."""
    from attekf.sim import SimConfig, simulate
    return simulate(SimConfig(duration_s=20.0, rate_hz=100.0, seed=3))


@pytest.fixture(scope="session")
def broad_dir() -> Path:
    """The directory of the 22 real BROAD trials (skips, or fails under CI, without them)."""
    return prereq.broad_dir()


@pytest.fixture(scope="session")
def broad_trial(broad_dir) -> Path:
    """Path of one real BROAD trial."""
    return broad_dir / "02_undisturbed_slow_rotation_B.hdf5"
