"""The vcan runner (tests/vm/vcan_run.py) wired to fake machines: every branch of the backend
choice, on any machine, never skipped (docs/hil.md, "Backends").

Two levels of fakes:

* machines: the runner's own code with the machine's facts (CPU flags, /dev/kvm, the kernel's
  answer to the XSTATE probe, host CAN) and the guests' boots replaced by what the kinds of
  machine seen so far did (a UML panic on a kernel that refuses UML's XSTATE write, a KVM guest
  that hangs silently or a QEMU that exits at once), plus kinds not seen yet (KVM that works, a
  kernel with CAN, a probe that cannot tell);
* processes: stand-ins for linux.uml and qemu-system-x86_64 run by the real boot code (init
  script, console files, the kill of a silent guest, the retry with the wrapper preloaded).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Tuple

import pytest

import hilutil

vcan_run = hilutil.vcan_run_module()
choice = hilutil.vm_module("vcan_choice")
guest = hilutil.vm_module("vcan_guest")
uml = hilutil.vm_module("vcan_uml")
qemu = hilutil.vm_module("vcan_qemu")

UML_PANIC = ("[    0.452000] userspace - ptrace set fp regs failed, errno = 14\r\n"
             "[    0.452000] Kernel panic - not syncing: Attempted to kill init! exitcode=0x0000000b\r\n")
QEMU_MSR = ("qemu-system-x86_64: error: failed to set MSR 0x10a to 0x69\n"
            "qemu-system-x86_64: ../../target/i386/kvm/kvm.c:3183: kvm_buf_set_msrs: "
            "Assertion `ret == cpu->kvm_msr_buf->nmsrs' failed.\n")


@dataclass
class Machine:
    """What a machine does, as the runner sees it."""
    flags: frozenset = frozenset({"avx", "xsave"})
    kvm_dev: Tuple[bool, bool] = (True, True)      # /dev/kvm exists, is read-write
    kvm: str = "hang"                              # a KVM guest: "works", "hang", "msr"
    probe: str = "probe_bytes=2696 host_bytes=2696 errno=0"   # xstate_selftest --probe (rc 0)
    uml_panics_unwrapped: bool = False             # UML without the wrapper: the AMX panic
    host_can: bool = False
    uml_installed: bool = True
    wrapper_builds: bool = True
    boots: list = field(default_factory=list)      # (backend, detail) of every boot


MACHINES = {
    # seen: docs/hil.md, "Machines seen"
    "xeon-amx": Machine(flags=frozenset({"avx512f", "amx_tile", "hypervisor"}), kvm="hang",
                        probe="probe_bytes=2696 host_bytes=11008 errno=14", uml_panics_unwrapped=True),
    "epyc-2440": Machine(flags=frozenset({"avx", "xsave"}), kvm="msr",
                         probe="probe_bytes=2696 host_bytes=2440 errno=0"),
    "epyc-2432": Machine(flags=frozenset({"avx512f", "xsave"}), kvm="msr",
                         probe="probe_bytes=2696 host_bytes=2432 errno=0"),
    # not seen yet
    "plain-2696": Machine(kvm_dev=(False, False)),
    "vmx-kvm": Machine(flags=frozenset({"vmx", "avx"}), kvm="works"),
    "can-kernel": Machine(host_can=True),
}


@pytest.fixture
def machine(monkeypatch):
    """Installs a Machine into the runner; returns a function that takes one and returns the
    installed copy (its boots recorded)."""
    def install(kind: Machine) -> Machine:
        m = dataclasses.replace(kind, boots=[])
        monkeypatch.setattr(vcan_run, "_failed", {})
        monkeypatch.setattr(vcan_run, "host_can_reason",
                            lambda: None if m.host_can else "this kernel has no CAN (fake)")
        monkeypatch.setattr(vcan_run, "_ensure_host_ifaces", lambda ifaces: None)
        monkeypatch.setattr(guest, "cpu_flags", lambda: set(m.flags))
        monkeypatch.setattr(qemu, "kvm_device", lambda: m.kvm_dev)
        monkeypatch.setattr(qemu, "available", lambda: None)
        monkeypatch.setattr(uml, "available",
                            lambda: None if m.uml_installed else "linux.uml not found (fake)")
        monkeypatch.setattr(uml, "version", lambda: (6, 1, 176))
        monkeypatch.setattr(uml, "probe_xstate_write", lambda: choice.parse_probe(0, m.probe, ""))

        def uml_boot(cmd, ifaces, timeout, env, cwd, mem, keep, wrap):
            m.boots.append(("uml", wrap))
            if wrap and not m.wrapper_builds:
                raise RuntimeError("no C compiler (fake)")
            if m.uml_panics_unwrapped and not wrap:
                return choice.outcome("uml", choice.Boot(-6, 0.5, 0.0, False, False),
                                      choice.GuestFiles(console=UML_PANIC), timeout)
            return choice.Result(0, "ran on uml", "", "uml", 2.0, boot_seconds=1.0)

        def qemu_run(cmd, ifaces, timeout, env, cwd, keep, accel):
            m.boots.append((f"qemu-{accel}", None))
            b = f"qemu-{accel}"
            if accel == "kvm" and m.kvm == "hang":
                return choice.outcome(b, choice.Boot(None, 6.1, 0.0, False, True), choice.GuestFiles(), timeout)
            if accel == "kvm" and m.kvm == "msr":
                return choice.outcome(b, choice.Boot(-6, 0.2, 0.0, False, False),
                                      choice.GuestFiles(extra=QEMU_MSR), timeout)
            return choice.Result(0, f"ran on {b}", "", b, 4.0, boot_seconds=3.0)

        def host_run(cmd, ifaces, timeout, env, cwd):
            m.boots.append(("host", None))
            return choice.Result(0, "ran on host", "", "host", 0.1)

        monkeypatch.setattr(uml, "_boot", uml_boot)
        monkeypatch.setattr(qemu, "run", qemu_run)
        monkeypatch.setattr(vcan_run, "_run_host", host_run)
        monkeypatch.delenv("ATTEKF_UML_XSTATE", raising=False)
        monkeypatch.delenv("ATTEKF_VCAN_MODE", raising=False)
        return m
    return install


def _wrapper_note(res):
    return next(n for n in res.notes if "XSTATE wrapper" in n)


# ---------------------------------------------------------------------------------------------
# Machines seen and not seen
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name, backend, uml_boots", [
    ("xeon-amx", "uml", [("uml", "auto")]),          # the kernel refuses: the wrapper at once
    ("epyc-2440", "uml", [("uml", None)]),           # the kernel accepts: no wrapper, no retry
    ("epyc-2432", "uml", [("uml", None)]),
    ("plain-2696", "uml", [("uml", None)]),
    ("vmx-kvm", "uml", [("uml", None)]),
    ("can-kernel", "host", []),
])
def test_auto_on_each_kind_of_machine(machine, capsys, name, backend, uml_boots):
    m = machine(MACHINES[name])
    res = vcan_run.run("true", timeout=30)
    assert res.mode == backend and res.stdout == f"ran on {backend}"
    assert [b for b in m.boots if b[0] == "uml"] == uml_boots
    if backend == "uml":
        note = _wrapper_note(res)
        assert ("XSTATE wrapper used" in note) == (uml_boots[0][1] == "auto"), note
        assert not any("retried" in n for n in res.notes)
    err = capsys.readouterr().err
    assert ("host: not usable: this kernel has no CAN (fake); trying uml" in err) == (backend != "host")


@pytest.mark.parametrize("name, backend, note", [
    ("xeon-amx", "qemu-tcg", "qemu-kvm: not usable: the CPU has no vmx/svm flag (/dev/kvm exists); trying qemu-tcg"),
    ("epyc-2440", "qemu-tcg", "qemu-kvm: not usable: the CPU has no vmx/svm flag (/dev/kvm exists); trying qemu-tcg"),
    ("plain-2696", "qemu-tcg", "qemu-kvm: not usable: no /dev/kvm (kvm module not loaded); trying qemu-tcg"),
    ("vmx-kvm", "qemu-kvm", None),
])
def test_qemu_mode_on_each_kind_of_machine(machine, capsys, name, backend, note):
    m = machine(MACHINES[name])
    res = vcan_run.run("true", mode="qemu", timeout=30)
    assert res.mode == backend
    err = capsys.readouterr().err
    assert (note in err) if note else err == ""
    assert [b for b, _ in m.boots] == [backend]          # a KVM that is not usable is not booted


@pytest.mark.parametrize("name, reason", [
    ("xeon-amx", "qemu-kvm: the guest printed nothing on its console in 6.1 s"),
    ("epyc-2440", "qemu-kvm: the guest did not report a status (exit -6): "
                  "qemu-system-x86_64: error: failed to set MSR 0x10a to 0x69"),
    ("plain-2696", "qemu-kvm: not usable: no /dev/kvm (kvm module not loaded)"),
])
def test_kvm_tried_past_the_flag_check_reports_what_it_did(machine, name, reason):
    machine(MACHINES[name])
    with pytest.raises(choice.VcanError) as e:
        vcan_run.run("true", mode="qemu-kvm", timeout=30, kvm_flags=False)
    assert str(e.value).startswith(reason)


def test_a_kvm_that_fails_falls_back_to_tcg_with_its_reason(machine, capsys):
    for kind, shown in (("hang", "the guest printed nothing on its console"),
                        ("msr", "failed to set MSR 0x10a to 0x69")):
        machine(Machine(flags=frozenset({"svm"}), kvm=kind))
        res = vcan_run.run("true", mode="qemu", timeout=30)
        assert res.mode == "qemu-tcg"
        assert res.notes[0].startswith("qemu-kvm: ") and shown in res.notes[0]
        assert "vcan_run: qemu-kvm: " in capsys.readouterr().err


# ---------------------------------------------------------------------------------------------
# The XSTATE wrapper: retry, setting, failures
# ---------------------------------------------------------------------------------------------
def test_a_panic_the_probe_did_not_foresee_is_retried_with_the_wrapper(machine, capsys):
    """E.g. a UML whose buffer is not the size probed: the kernel accepted the probe's write,
    UML panics all the same; the runner boots once more with the wrapper."""
    m = machine(Machine(uml_panics_unwrapped=True))
    res = vcan_run.run("true", timeout=30)
    assert res.mode == "uml" and m.boots == [("uml", None), ("uml", "auto")]
    assert any(n.startswith("uml: retried with the XSTATE wrapper after: ") and "errno = 14" in n
               for n in res.notes), res.notes
    err = capsys.readouterr().err
    assert len([ln for ln in err.splitlines() if "retrying with it" in ln]) == 1, err


def test_a_probe_that_cannot_tell_leaves_it_to_the_retry(machine):
    m = machine(Machine(uml_panics_unwrapped=True))
    m.probe = "nothing"
    res = vcan_run.run("true", timeout=30)
    assert res.mode == "uml" and [w for _, w in m.boots] == [None, "auto"]
    assert "could not run" in _wrapper_note(res)


def test_a_wrapper_that_cannot_be_built(machine):
    m = machine(MACHINES["xeon-amx"])
    m.wrapper_builds = False
    res = vcan_run.run("true", timeout=30)       # UML given up with the reason, QEMU/TCG runs
    assert res.mode == "qemu-tcg"
    assert any("uml: needs the XSTATE wrapper, which cannot be built: no C compiler (fake)" in n
               for n in res.notes), res.notes


@pytest.mark.parametrize("setting, wraps", [("on", ["auto"]), ("full", ["full"])])
def test_the_wrapper_forced(machine, monkeypatch, setting, wraps):
    m = machine(MACHINES["epyc-2440"])
    monkeypatch.setenv("ATTEKF_UML_XSTATE", setting)
    res = vcan_run.run("true", mode="uml", timeout=30)
    assert [w for _, w in m.boots] == wraps and f"ATTEKF_UML_XSTATE={setting}" in _wrapper_note(res)


def test_wrapper_off_no_backend_left_and_every_reason_named(machine, monkeypatch, capsys):
    m = machine(MACHINES["xeon-amx"])
    monkeypatch.setenv("ATTEKF_UML_XSTATE", "off")
    monkeypatch.setattr(qemu, "available", lambda: "qemu-system-x86_64 not found (fake)")
    with pytest.raises(choice.VcanError) as e:
        vcan_run.run("true", timeout=30)
    msg = str(e.value)
    assert "host: not usable: this kernel has no CAN (fake)" in msg
    assert "uml: the guest did not report a status (exit -6): userspace - ptrace set fp regs failed, " \
           "errno = 14; Kernel panic - not syncing: Attempted to kill init!" in msg
    assert "qemu-kvm: not usable: qemu-system-x86_64 not found (fake)" in msg
    assert "qemu-tcg: not usable: qemu-system-x86_64 not found (fake)" in msg
    assert m.boots == [("uml", None)]                     # no retry when off
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("vcan_run: ")]
    assert [ln.split(":")[1].strip() for ln in err] == ["host", "uml", "qemu-kvm", "qemu-tcg"], err


def test_uml_not_installed_goes_to_qemu(machine):
    m = machine(Machine(uml_installed=False))
    assert vcan_run.run("true", timeout=30).mode == "qemu-tcg"
    assert [b for b, _ in m.boots] == ["qemu-tcg"]


def test_backend_status_without_booting(machine):
    m = machine(MACHINES["epyc-2440"])
    st = vcan_run.backend_status()
    assert st == {"host": ("this kernel has no CAN (fake)", False), "uml": (None, True),
                  "qemu-kvm": ("the CPU has no vmx/svm flag (/dev/kvm exists)", False),
                  "qemu-tcg": (None, True)}
    assert m.boots == []


def test_mode_from_the_environment(machine, monkeypatch):
    machine(MACHINES["epyc-2440"])
    monkeypatch.setenv("ATTEKF_VCAN_MODE", "qemu-tcg")
    assert vcan_run.run("true", timeout=30).mode == "qemu-tcg"
    monkeypatch.setenv("ATTEKF_VCAN_MODE", "nonsense")
    with pytest.raises(ValueError, match="mode must be one of"):
        vcan_run.run("true", timeout=30)
    monkeypatch.setenv("ATTEKF_VCAN_MODE", "auto")
    monkeypatch.setenv("ATTEKF_UML_XSTATE", "sometimes")
    with pytest.raises(ValueError, match="ATTEKF_UML_XSTATE must be one of"):
        vcan_run.run("true", timeout=30)


# ---------------------------------------------------------------------------------------------
# Processes: stand-ins for linux.uml and qemu-system-x86_64 run by the real boot code
# ---------------------------------------------------------------------------------------------
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
# stands in for qemu-system-x86_64: under KVM hangs silently ($FAKE_KVM=hang) or fails at once
# (msr); under TCG runs the init's command
while [ $# -gt 0 ]; do
  case "$1" in -accel) ACCEL=$2; shift ;; -append) APPEND=$2; shift ;; esac; shift
done
if [ "$ACCEL" = kvm ]; then
  [ "$FAKE_KVM" = hang ] && exec sleep 60
  echo "qemu-system-x86_64: error: failed to set MSR 0x10a to 0x69" >&2
  kill -ABRT $$
fi
INIT=${APPEND##* }
W=$(sed -n 's/^W=//p' "$INIT")
cat /proc/uptime > "$W/started"; echo fake-qemu-ok > "$W/stdout"; echo 0 > "$W/status"
"""


def _script(path, text):
    path.write_text(text)
    path.chmod(0o755)
    return str(path)


@pytest.fixture
def fake_programs(tmp_path, monkeypatch):
    """The runner with stand-in programs for linux.uml and QEMU; the XSTATE wrapper really
    built (the stand-in UML looks for it in LD_PRELOAD), the probe answering "accepted" so
    that the first boot is without it."""
    try:
        uml.build_xstate_tools()
    except RuntimeError as e:
        pytest.fail(f"cannot build the XSTATE wrapper: {e}", pytrace=False)
    monkeypatch.setattr(vcan_run, "_failed", {})
    monkeypatch.setattr(vcan_run, "host_can_reason", lambda: "this kernel has no CAN (fake)")
    monkeypatch.setattr(uml, "UML_KERNEL", _script(tmp_path / "linux.uml", FAKE_UML))
    monkeypatch.setattr(uml, "_version", None)
    monkeypatch.setattr(uml, "available", lambda: None)
    monkeypatch.setattr(uml, "probe_xstate_write",
                        lambda: choice.parse_probe(0, "probe_bytes=2696 host_bytes=2440 errno=0", ""))
    monkeypatch.setattr(qemu, "QEMU", _script(tmp_path / "qemu-system-x86_64", FAKE_QEMU))
    monkeypatch.setattr(qemu, "available", lambda: None)
    monkeypatch.setattr(guest, "cpu_flags", lambda: {"vmx"})
    monkeypatch.setattr(qemu, "kvm_device", lambda: (True, True))
    monkeypatch.setattr(qemu, "KVM_MARKER_S", 1.0)
    kernel = {"dir": str(tmp_path), "vmlinuz": "vmlinuz", "vmlinux": "vmlinux", "package": "stand-in 1 1"}
    monkeypatch.setattr(qemu, "cached_kernel", lambda: kernel)
    monkeypatch.setattr(qemu, "boot_image", lambda k: "vmlinux")
    monkeypatch.setattr(qemu, "initramfs", lambda k: "initramfs.img")
    monkeypatch.delenv("ATTEKF_UML_XSTATE", raising=False)
    monkeypatch.delenv("ATTEKF_VCAN_MODE", raising=False)


def test_process_uml_panic_and_retry(fake_programs, capsys):
    res = vcan_run.run("true", timeout=30)
    assert res.mode == "uml" and res.stdout.strip() == "fake-uml-ok"
    assert any("retried with the XSTATE wrapper after" in n and "ptrace set fp regs failed, errno = 14" in n
               for n in res.notes), res.notes
    err = capsys.readouterr().err
    assert len([ln for ln in err.splitlines() if "retrying with it" in ln]) == 1, err


@pytest.mark.parametrize("kvm, shown", [("hang", "the guest printed nothing on its console in 1."),
                                        ("msr", "exit -6): qemu-system-x86_64: error: failed to set MSR 0x10a")])
def test_process_kvm_failure_detected_then_tcg(fake_programs, monkeypatch, kvm, shown):
    monkeypatch.setenv("FAKE_KVM", kvm)
    res = vcan_run.run("true", mode="qemu", timeout=30)
    assert res.mode == "qemu-tcg" and res.stdout.strip() == "fake-qemu-ok"
    assert res.notes[0].startswith("qemu-kvm: ") and shown in res.notes[0], res.notes
    assert res.seconds < 10


def test_process_forced_backend_error_carries_its_evidence(fake_programs, monkeypatch):
    monkeypatch.setenv("ATTEKF_UML_XSTATE", "off")
    with pytest.raises(choice.BackendError) as e:
        vcan_run.run("true", mode="uml", timeout=30)
    assert str(e.value).startswith("uml: the guest did not report a status")
    assert e.value.cause and all(part.strip() in e.value.evidence for part in e.value.cause.split("; "))
