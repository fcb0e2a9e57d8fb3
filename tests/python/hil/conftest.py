"""Fixtures of the hardware-in-loop tests (tests/python/hil): the vcan runner and the node.

The HIL needs one of the backends of tests/vm/vcan_run.py: a kernel with CAN, user-mode Linux
or QEMU. On a machine with none the tests skip with the reasons, except under CI (CI=true),
where they fail: the project's set-up installs UML and QEMU, so none usable there is a broken
set-up. A backend that cannot be used on this machine is reported, not a failure, as long as
one works (test_vcan_backends.py)."""

from __future__ import annotations

import os

import pytest

import hilutil
import prereq

def pytest_terminal_summary(terminalreporter):
    """The measured loss and latency lines (hilutil.report) at the end of the run."""
    if hilutil.REPORT:
        terminalreporter.section("hardware-in-loop measurements")
        for line in hilutil.REPORT:
            terminalreporter.write_line(line)


@pytest.fixture(scope="session")
def vcan():
    """The vcan_run module, checked to have at least one usable backend."""
    mod = hilutil.vcan_run_module()
    status = mod.backend_status()
    if all(why for why, _expected in status.values()):
        prereq.unavailable("HIL not run: no vcan backend works here: "
                           + "; ".join(f"{b}: {why}" for b, (why, _e) in status.items()))
    return mod


@pytest.fixture(scope="session")
def node():
    path = hilutil.node_binary()
    if not os.access(path, os.X_OK):
        pytest.fail(f"{path} is not built: cmake --build build/host (or set ATTEKF_NODE)", pytrace=False)
    return path
