"""The fallback logic of hal/tools/vcan_run.py on any machine, with stand-ins for linux.uml and
qemu-system-x86_64 that fail the way the real ones were seen to (docs/hil.md, "Backends"):
UML's panic on a CPU with AMX when the XSTATE wrapper is not loaded, and a KVM guest that
hangs without printing anything where /dev/kvm exists but the CPU has no vmx/svm. Checked:
the retry with the wrapper, one log line per fallback with its root cause, the root cause in
the error text, and an error that names every backend's reason. Where this machine has such a
/dev/kvm, the real QEMU's silent hang is detected too."""

from __future__ import annotations

import os
import shutil

import pytest

FAKE_UML = r"""#!/bin/sh
# stands in for linux.uml: panics like UML 6.1 on a CPU with AMX unless the wrapper is preloaded
[ "$1" = --version ] && { echo 6.1.176; exit 0; }
for a in "$@"; do case "$a" in init=*) INIT=${a#init=} ;; esac; done
W=$(sed -n 's/^W=//p' "$INIT")
case "$LD_PRELOAD" in
  *libxstate_ptrace*) cat /proc/uptime > "$W/started"; echo fake-uml-ok > "$W/stdout"
                      echo 0 > "$W/status"; exit 0 ;;
esac
echo "[    0.5] userspace - ptrace set fp regs failed, errno = 14"
echo "[    0.5] Kernel panic - not syncing: Attempted to kill init! exitcode=0x0000000b"
kill -ABRT $$
"""

FAKE_QEMU = r"""#!/bin/sh
# stands in for qemu-system-x86_64: under KVM hangs silently, under TCG runs the init's command
while [ $# -gt 0 ]; do
  case "$1" in -accel) ACCEL=$2; shift ;; -append) APPEND=$2; shift ;; esac; shift
done
[ "$ACCEL" = kvm ] && exec sleep 60
INIT=${APPEND##* }
W=$(sed -n 's/^W=//p' "$INIT")
cat /proc/uptime > "$W/started"; echo fake-qemu-ok > "$W/stdout"; echo 0 > "$W/status"
"""


def _script(path, text):
    path.write_text(text)
    path.chmod(0o755)
    return str(path)


@pytest.fixture
def fakes(vcan, tmp_path, monkeypatch):
    """vcan_run with fake UML and QEMU; the XSTATE wrapper really built (the fake UML looks
    for it in LD_PRELOAD)."""
    import sys
    uml, qemu = sys.modules["vcan_uml"], sys.modules["vcan_qemu"]
    try:
        uml.build_xstate_tools()
    except RuntimeError as e:
        pytest.fail(f"cannot build the XSTATE wrapper: {e}", pytrace=False)
    monkeypatch.setattr(vcan, "_failed", {})
    monkeypatch.setattr(vcan, "host_can_reason", lambda: "this kernel has no CAN (stand-in)")
    monkeypatch.setattr(uml, "UML_KERNEL", _script(tmp_path / "linux.uml", FAKE_UML))
    monkeypatch.setattr(uml, "_version", None)
    monkeypatch.setattr(uml, "available", lambda: None)
    monkeypatch.setattr(uml, "wrapper_needed", lambda: (False, "pretended by the test"))
    monkeypatch.setattr(qemu, "QEMU", _script(tmp_path / "qemu-system-x86_64", FAKE_QEMU))
    monkeypatch.setattr(qemu, "available", lambda: None)
    monkeypatch.setattr(qemu, "kvm_usable", lambda: None)
    monkeypatch.setattr(qemu, "KVM_MARKER_S", 1.0)
    kernel = {"dir": str(tmp_path), "vmlinuz": "vmlinuz", "vmlinux": "vmlinux", "package": "stand-in 1 1"}
    monkeypatch.setattr(qemu, "cached_kernel", lambda: kernel)
    monkeypatch.setattr(qemu, "boot_image", lambda k: "vmlinux")
    monkeypatch.setattr(qemu, "initramfs", lambda k: "initramfs.img")
    monkeypatch.delenv("ATTEKF_UML_XSTATE", raising=False)
    monkeypatch.delenv("ATTEKF_VCAN_MODE", raising=False)
    return vcan, uml, qemu


def test_uml_retries_with_the_wrapper(fakes, capsys):
    vcan, _uml, _qemu = fakes
    res = vcan.run("true", mode="auto", timeout=30)
    assert res.mode == "uml" and res.stdout.strip() == "fake-uml-ok"
    assert any("retried with the XSTATE wrapper after" in n and "ptrace set fp regs failed, errno = 14" in n
               for n in res.notes), res.notes
    err = capsys.readouterr().err.splitlines()
    assert [ln for ln in err if ln.startswith("vcan_run: host: this kernel has no CAN (stand-in); trying uml")]
    assert len([ln for ln in err if "retrying with it" in ln]) == 1, err


def test_root_cause_in_the_error_and_every_backend_named(fakes, monkeypatch, capsys):
    vcan, _uml, qemu = fakes
    monkeypatch.setenv("ATTEKF_UML_XSTATE", "off")
    monkeypatch.setattr(qemu, "available", lambda: "qemu-system-x86_64 not found (stand-in)")
    with pytest.raises(vcan.VcanError) as e:
        vcan.run("true", mode="auto", timeout=30)
    msg = str(e.value)
    assert "host: this kernel has no CAN (stand-in)" in msg
    assert "uml: " in msg and "ptrace set fp regs failed, errno = 14" in msg and "Kernel panic" in msg
    assert "qemu-kvm: not usable: qemu-system-x86_64 not found (stand-in)" in msg
    assert "qemu-tcg: not usable: qemu-system-x86_64 not found (stand-in)" in msg
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("vcan_run: ")]
    # one line per backend, each but the last naming the next one tried
    assert [ln.split(":")[1].strip() for ln in err] == ["host", "uml", "qemu-kvm", "qemu-tcg"], err
    assert all("; trying " in ln for ln in err[:3]) and "; trying " not in err[3], err
    # a forced backend: its own reason, no fallback
    with pytest.raises(vcan.VcanError, match=r"^uml: .*ptrace set fp regs failed"):
        vcan.run("true", mode="uml", timeout=30)


def test_silent_kvm_falls_back_to_tcg(fakes, capsys):
    vcan, _uml, _qemu = fakes
    res = vcan.run("true", mode="qemu", timeout=30)
    assert res.mode == "qemu-tcg" and res.stdout.strip() == "fake-qemu-ok"
    assert any(n.startswith("qemu-kvm: the guest printed nothing on its console") for n in res.notes), res.notes
    err = capsys.readouterr().err
    assert "vcan_run: qemu-kvm: the guest printed nothing on its console" in err and "trying qemu-tcg" in err


def test_mode_from_the_environment(fakes, monkeypatch):
    vcan, _uml, _qemu = fakes
    monkeypatch.setenv("ATTEKF_VCAN_MODE", "qemu-tcg")
    assert vcan.run("true", timeout=30).mode == "qemu-tcg"
    monkeypatch.setenv("ATTEKF_VCAN_MODE", "nonsense")
    with pytest.raises(ValueError, match="mode must be one of"):
        vcan.run("true", timeout=30)


def test_real_kvm_without_vmx_is_detected(vcan, monkeypatch):
    """On a machine whose /dev/kvm exists while the CPU shows no vmx/svm (as on some cloud
    VMs), a KVM guest hangs before its first console line; the runner must see that."""
    import sys
    qemu = sys.modules["vcan_qemu"]
    flags = sys.modules["vcan_guest"].cpu_flags()
    if not os.path.exists("/dev/kvm") or {"vmx", "svm"} & flags:
        pytest.skip("needs a /dev/kvm without vmx/svm (this machine: "
                    + ("vmx/svm present" if {"vmx", "svm"} & flags else "no /dev/kvm") + ")")
    if qemu.available() or shutil.which(qemu.QEMU) is None:
        pytest.skip(f"QEMU not usable here: {qemu.available()}")
    monkeypatch.setattr(qemu, "kvm_usable", lambda: None)
    with pytest.raises(sys.modules["vcan_guest"].BackendError, match="printed nothing on its console"):
        qemu.run("true", ["vcan0"], 60, dict(os.environ), "/tmp", False, "kvm")
