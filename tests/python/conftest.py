"""Shared fixtures of the Python tests (host tools). Keep small: sub-folders add their own."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
# $ATTEKF_BROAD_DIR, else ../shared/data/broad next to the repository (as attekf.bench)
BROAD_DIR = Path(os.environ.get("ATTEKF_BROAD_DIR") or REPO.parent / "shared" / "data" / "broad")


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO


@pytest.fixture(scope="session")
def sim_recording():
    """A 20 s simulated recording with magnetometer and truth (session-wide; do not modify)."""
    from attekf.sim import SimConfig, simulate
    return simulate(SimConfig(duration_s=20.0, rate_hz=100.0, seed=3))


@pytest.fixture(scope="session")
def broad_trial() -> Path:
    """Path of one real BROAD trial; skips (visibly, with -ra) when the data is absent."""
    path = BROAD_DIR / "02_undisturbed_slow_rotation_B.hdf5"
    if not path.exists():
        pytest.skip(f"BROAD data not found at {BROAD_DIR} (set ATTEKF_BROAD_DIR)")
    return path
