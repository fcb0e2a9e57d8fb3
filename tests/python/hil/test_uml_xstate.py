"""The ptrace XSTATE wrapper that lets user-mode Linux < 6.13 run on CPUs with a larger XSAVE
area than it was built for (AMX; hal/tools/uml_xstate/, docs/hil.md).

A CPU without AMX never shows UML's panic, so the wrapper is tested directly on every machine:
its self-test moves a stopped child's FPU state through it with buffers of the host's size
(passed through) and smaller ones (host-sized path: the kernel alone refuses those writes), in
its three modes; and a UML guest boots with the wrapper forced through its host-sized path for
every call, running vector code in parallel processes whose results must equal the host's.
Where the CPU needs the wrapper, UML without it must fail with the panic's root cause in the
error, and the runner's retry must recover from that panic."""

from __future__ import annotations

import os
import platform
import re
import subprocess
import sys

import pytest

import hilutil

NUMPY_WORK = ("import numpy as np; a = np.arange(1, 200001, dtype=np.float64); "
              "r = [float(np.sum(np.sqrt(a) * np.sin(a / 7.0))) for _ in range(30)]; "
              "assert len(set(r)) == 1, r; print(repr(r[0]))")


@pytest.fixture(scope="module")
def uml(vcan):
    mod = sys.modules["vcan_uml"]
    if platform.machine() not in ("x86_64", "AMD64"):
        pytest.skip(f"the XSTATE wrapper is for x86-64 (this is {platform.machine()})")
    return mod


@pytest.fixture(scope="module")
def tools(uml):
    try:
        return uml.build_xstate_tools()
    except RuntimeError as e:
        pytest.fail(f"cannot build the XSTATE wrapper: {e}", pytrace=False)


@pytest.mark.parametrize("mode", ["auto", "full", "pass"])
def test_wrapper_selftest(tools, mode):
    env = dict(os.environ, LD_PRELOAD=tools["lib"], ATTEKF_XSTATE_WRAP=mode)
    p = subprocess.run([tools["selftest"]], capture_output=True, text=True, env=env, timeout=60)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr
    summary = re.search(r"xstate_selftest: (\d+) checks, (\d+) failed", p.stdout)
    assert summary and summary.group(2) == "0", p.stdout[-3000:]
    smaller = re.findall(r"smaller write [^\n]*\((\d+) bytes\)", p.stdout)
    assert smaller, "no buffer smaller than the host's was tried"
    info = subprocess.run([tools["selftest"], "--info"], capture_output=True, text=True).stdout.split()[0]
    hilutil.report(f"XSTATE wrapper self-test, mode {mode}: {summary.group(1)} checks passed; {info}, "
                   f"caller sizes {', '.join(sorted(set(smaller), key=int))}")


def test_uml_boots_with_the_wrapper_forced_full(vcan, uml, tools, monkeypatch, tmp_path):
    """Every XSTATE read and write of the guest's life through the host-sized path; numpy's
    vector code in two parallel guest processes gives the host's result every time."""
    if uml.available():
        pytest.skip(f"UML not usable here: {uml.available()}")
    py = os.environ.get("ATTEKF_PYTHON", sys.executable)
    host = subprocess.run([py, "-c", NUMPY_WORK], capture_output=True, text=True, check=True).stdout.strip()
    monkeypatch.setenv("ATTEKF_UML_XSTATE", "full")
    q = f"{py} -c '{NUMPY_WORK}'"
    res = vcan.run(f"{q} > \"$PWD/a.txt\" & {q} > \"$PWD/b.txt\"; wait; cat \"$PWD/a.txt\" \"$PWD/b.txt\"",
                   mode="uml", timeout=300, cwd=str(tmp_path))
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == [host, host]
    note = next((n for n in res.notes if "XSTATE wrapper (mode full)" in n), "")
    writes = re.search(r"writes host-sized (\d+)", note)
    reads = re.search(r"reads host-sized (\d+)", note)
    assert writes and reads and int(writes.group(1)) > 0 and int(reads.group(1)) > 0, res.notes
    assert "failed 0" in note, note
    hilutil.report(f"UML with the wrapper forced full: {reads.group(1)} reads and {writes.group(1)} "
                   f"writes host-sized, numpy results equal to the host's")


def _needs_wrapper(uml):
    if uml.available():
        pytest.skip(f"UML not usable here: {uml.available()}")
    need, why = uml.wrapper_needed()
    if not need:
        pytest.skip(f"this CPU does not make UML panic ({why}); the self-test covers the wrapper")
    return why


def test_uml_without_the_wrapper_fails_with_the_root_cause(vcan, uml, monkeypatch):
    _needs_wrapper(uml)
    monkeypatch.setenv("ATTEKF_UML_XSTATE", "off")
    with pytest.raises(vcan.VcanError) as e:
        vcan.run("true", mode="uml", timeout=120)
    assert "ptrace set fp regs failed, errno = 14" in str(e.value)
    assert "Kernel panic" in str(e.value)


def test_uml_retries_with_the_wrapper_after_the_panic(vcan, uml, monkeypatch, capsys):
    """The runner's retry, on a real panic: the CPU check is made to say "not needed"."""
    _needs_wrapper(uml)
    monkeypatch.delenv("ATTEKF_UML_XSTATE", raising=False)
    monkeypatch.setattr(uml, "wrapper_needed", lambda: (False, "pretended by the test"))
    res = vcan.run("echo retried-ok", mode="uml", timeout=120)
    assert res.returncode == 0 and res.stdout.strip() == "retried-ok"
    assert any("retried with the XSTATE wrapper after" in n and "ptrace set fp regs failed" in n
               for n in res.notes), res.notes
    err = capsys.readouterr().err
    assert len([ln for ln in err.splitlines() if "retrying with it" in ln]) == 1, err
