"""Fixtures of the hardware-in-loop tests (tests/python/hil): the vcan runner and the node.

The HIL needs a kernel with CAN (vcan) or user-mode Linux (hal/tools/vcan_run.py). On a machine
with neither the tests skip with the reason, except under CI (CI=true), where they fail: the
project's set-up installs user-mode-linux, so a missing UML there is a broken set-up."""

from __future__ import annotations

import os

import pytest

import hilutil

def pytest_terminal_summary(terminalreporter):
    """The measured loss and latency lines (hilutil.report) at the end of the run."""
    if hilutil.REPORT:
        terminalreporter.section("hardware-in-loop measurements")
        for line in hilutil.REPORT:
            terminalreporter.write_line(line)


def _unavailable(reason: str):
    if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
        pytest.fail(f"HIL cannot run on this CI machine: {reason}", pytrace=False)
    pytest.skip(f"HIL not run: {reason}")


@pytest.fixture(scope="session")
def vcan():
    """The vcan_run module, checked usable (host CAN or UML)."""
    mod = hilutil.vcan_run_module()
    if not mod.host_has_can():
        why = mod.uml_available()
        if why:
            _unavailable(why)
    return mod


@pytest.fixture(scope="session")
def node():
    path = hilutil.node_binary()
    if not os.access(path, os.X_OK):
        pytest.fail(f"{path} is not built: cmake --build build/host (or set ATTEKF_NODE)", pytrace=False)
    return path
