"""The ptrace XSTATE wrapper that lets user-mode Linux < 6.13 run where the host kernel refuses
its XSTATE writes (a CPU whose XSAVE area is larger than UML's buffer: AMX), and the probe that
asks the kernel whether it does (tests/vm/uml_xstate/, docs/hil.md).

Whether UML needs the wrapper depends on the CPU, so the wrapper is tested directly on every
machine: its self-test moves a stopped child's FPU state through it with buffers of the host's
size (passed through) and smaller ones (host-sized path: the kernel alone refuses those
writes), in its three modes; and a UML guest boots with the wrapper forced through its
host-sized path for every call, running vector code in parallel processes whose results must
equal the host's. UML without the wrapper either boots or fails with the root cause it showed,
and what it did must agree with the probe's answer (the runner's choice rests on it); the
runner's retry after the panic is tested with fakes (test_vcan_fallback.py)."""

from __future__ import annotations

import errno
import os
import platform
import re
import subprocess
import sys

import pytest

import hilutil
import prereq

NUMPY_WORK = ("import numpy as np; a = np.arange(1, 200001, dtype=np.float64); "
              "r = [float(np.sum(np.sqrt(a) * np.sin(a / 7.0))) for _ in range(30)]; "
              "assert len(set(r)) == 1, r; print(repr(r[0]))")


@pytest.fixture(scope="module")
def uml():
    if platform.machine() not in ("x86_64", "AMD64"):
        pytest.skip(f"the XSTATE wrapper is for x86-64 (this is {platform.machine()})")
    return hilutil.vm_module("vcan_uml")


@pytest.fixture(scope="module")
def tools(uml):
    try:
        return uml.build_xstate_tools()
    except RuntimeError as e:
        pytest.fail(f"cannot build the XSTATE wrapper: {e}", pytrace=False)


def _uml_usable(uml):
    why = uml.available()
    if why:
        prereq.unavailable(f"UML not usable here: {why}")


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


def test_probe_reports_the_kernels_answer(tools):
    """The kernel takes an XSTATE write of its own size or larger (it uses its part) and
    refuses a smaller one with EFAULT; the probe must report exactly that."""
    def probe(n):
        p = subprocess.run([tools["selftest"], "--probe", str(n)], capture_output=True, text=True, timeout=20)
        assert p.returncode == 0, p.stderr
        m = re.fullmatch(r"probe_bytes=(\d+) host_bytes=(\d+) errno=(\d+)\n", p.stdout)
        assert m, p.stdout
        return int(m.group(2)), int(m.group(3))
    host, e = probe(576)
    assert e == (errno.EFAULT if host > 576 else 0)
    assert probe(host) == (host, 0) and probe(host + 64) == (host, 0)
    if host > 1024:
        assert probe(host - 64) == (host, errno.EFAULT)
    bad = subprocess.run([tools["selftest"], "--probe", "577"], capture_output=True, text=True, timeout=20)
    assert bad.returncode == 2 and "multiple of 8" in bad.stderr


def test_uml_boots_with_the_wrapper_forced_full(vcan, uml, tools, monkeypatch, tmp_path):
    """Every XSTATE read and write of the guest's life through the host-sized path; numpy's
    vector code in two parallel guest processes gives the host's result every time."""
    _uml_usable(uml)
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


def test_uml_without_the_wrapper_agrees_with_the_probe(vcan, uml, monkeypatch):
    """UML without the wrapper: it runs the command, or it fails with the root cause it showed.
    For a UML with a buffer fixed at build time the probe must have foreseen which: a UML that
    ran had its XSTATE writes accepted, one that died of EFAULT on them had them refused (a
    probe of the wrong size would disagree). The full suite's guest counts when it was such a
    boot."""
    _uml_usable(uml)
    choice = hilutil.vm_module("vcan_choice")
    probe = uml.probe_xstate_write()
    if probe.errno is None:
        pytest.fail(probe.detail, pytrace=False)
    fixed = not (uml.version() and uml.version()[:2] >= choice.UML_XSTATE_FIXED_IN)
    if any(r.mode == "uml" and _without_the_wrapper(r) for r in hilutil.FULL_SUITE):
        assert probe.errno == 0 or not fixed, f"UML ran without the wrapper although {probe.detail}"
        hilutil.report(f"UML without the XSTATE wrapper: ran the full suite; probe: {probe.detail}")
        return
    monkeypatch.setenv("ATTEKF_UML_XSTATE", "off")
    try:
        res = vcan.run("echo without-the-wrapper", mode="uml", timeout=120)
    except vcan.BackendError as e:
        reason = hilutil.check_reported_cause(e)
        if fixed and choice.FP_REGS_FAILED in e.cause:
            assert "errno = 14" in e.cause and probe.errno == errno.EFAULT, (reason, probe.detail)
        hilutil.report(f"UML without the XSTATE wrapper: {reason}; probe: {probe.detail}")
        return
    assert res.returncode == 0 and res.stdout.strip() == "without-the-wrapper"
    assert probe.errno == 0 or not fixed, f"UML ran without the wrapper although {probe.detail}"
    hilutil.report(f"UML without the XSTATE wrapper: ran; probe: {probe.detail}")


def _without_the_wrapper(res) -> bool:
    """Whether a UML run booted without the wrapper: planned so, and not retried with it."""
    return (any(n.startswith("uml: XSTATE wrapper not needed") for n in res.notes)
            and not any("retried with the XSTATE wrapper" in n for n in res.notes))
