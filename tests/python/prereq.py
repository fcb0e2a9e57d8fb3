"""What a test needs from the machine, and what happens when it is missing.

A CI machine is set up by scripts/setup.sh, which installs every tool, and sees the BROAD data
next to the repository: there a missing prerequisite is a broken set-up and fails the test
(CI=true, exported by .ci/run). On a developer's machine the test skips and says why
(pytest -ra lists every skip with its reason)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
# The real recordings live beside the repository, never inside it (README, "Data").
BROAD_DIR = Path(os.environ.get("ATTEKF_BROAD_DIR", REPO.parent / "shared" / "data" / "broad"))
BROAD_TRIALS = 22  # the development set: every trial of ../shared/data/broad


def in_ci() -> bool:
    return os.environ.get("CI", "").strip().lower() in ("1", "true", "yes")


def unavailable(reason: str) -> None:
    """Fails (CI=true) or skips (elsewhere) the running test because `reason` is missing."""
    if in_ci():
        pytest.fail(f"{reason} (CI=true: a missing prerequisite fails the run)", pytrace=False)
    pytest.skip(reason)


def broad_dir() -> Path:
    """The BROAD data directory with all its trials, or unavailable()."""
    found = sorted(BROAD_DIR.glob("*.hdf5")) if BROAD_DIR.is_dir() else []
    if len(found) != BROAD_TRIALS:
        unavailable(f"BROAD data not found at {BROAD_DIR} ({len(found)} of {BROAD_TRIALS} trials; "
                    f"set ATTEKF_BROAD_DIR)")
    return BROAD_DIR
