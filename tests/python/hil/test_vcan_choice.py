"""The vcan runner's decisions (tests/vm/vcan_choice.py), pure logic fed with fakes: which
backends a mode tries, the fallback between them, the XSTATE wrapper's plan and its retry,
the KVM pre-check, the root cause found in a guest's output and the outcome of a finished
guest. The fakes copy what real machines showed (docs/hil.md, "Machines seen"); no process
is started, nothing depends on this machine, nothing is skipped."""

from __future__ import annotations

import errno

import pytest

import hilutil

choice = hilutil.vm_module("vcan_choice")

UML_PANIC = ("Linux version 6.1.176 (Debian 6.1.176-1um4)\r\n"
             "[    0.452000] userspace - ptrace set fp regs failed, errno = 14\r\n"
             "[    0.452000] Kernel panic - not syncing: Attempted to kill init! exitcode=0x0000000b\r\n")
QEMU_MSR = ("qemu-system-x86_64: error: failed to set MSR 0x10a to 0x69\n"
            "qemu-system-x86_64: ../../target/i386/kvm/kvm.c:3183: kvm_buf_set_msrs: "
            "Assertion `ret == cpu->kvm_msr_buf->nmsrs' failed.\n")
CPUINFO_AMX = "processor\t: 0\nmodel name\t: Intel(R) Xeon(R) Platinum\nflags\t\t: fpu sse xsave avx avx512f amx_tile hypervisor\n"
CPUINFO_EPYC = "processor\t: 0\nmodel name\t: AMD EPYC\nflags\t\t: fpu sse xsave avx\n"
CPUINFO_VMX = "processor\t: 0\nflags\t\t: fpu sse vmx xsave avx\n"


# ---------------------------------------------------------------------------------------------
# Order and fallback
# ---------------------------------------------------------------------------------------------
def test_order_of_each_mode():
    assert choice.order("auto") == (["host", "uml", "qemu-kvm", "qemu-tcg"], True)
    assert choice.order("qemu") == (["qemu-kvm", "qemu-tcg"], True)
    for b in choice.BACKENDS:
        assert choice.order(b) == ([b], False)
    with pytest.raises(ValueError, match="mode must be one of"):
        choice.order("kvm")


class Backends:
    """Fake backends: precheck reasons, and per attempt a Result or a BackendError."""

    def __init__(self, unusable=None, boots=None):
        self.unusable = unusable or {}
        self.boots = boots or {}
        self.attempted = []
        self.lines = []

    def precheck(self, b):
        return self.unusable.get(b)

    def attempt(self, b):
        self.attempted.append(b)
        what = self.boots.get(b, "ok")
        if isinstance(what, Exception):
            raise what
        return choice.Result(0, f"ran on {b}", "", b, 1.0)

    def run(self, mode, failed=None):
        backends, fallback = choice.order(mode)
        return choice.first_working(backends, fallback, self.precheck, self.attempt,
                                    {} if failed is None else failed, self.lines.append)


def panic(b="uml"):
    return choice.BackendError(b, "the guest did not report a status (exit -6): userspace - ptrace "
                                  "set fp regs failed, errno = 14", evidence=UML_PANIC)


def test_the_first_usable_backend_runs():
    f = Backends(unusable={"host": "this kernel has no CAN (fake)"})
    res = f.run("auto")
    assert res.mode == "uml" and f.attempted == ["uml"]
    assert f.lines == ["host: not usable: this kernel has no CAN (fake); trying uml"]
    assert res.notes == []


def test_a_failed_boot_falls_back_with_its_reason_logged_and_noted():
    f = Backends(unusable={"host": "no CAN (fake)", "qemu-kvm": "the CPU has no vmx/svm flag (fake)"},
                 boots={"uml": panic()})
    res = f.run("auto")
    assert res.mode == "qemu-tcg" and f.attempted == ["uml", "qemu-tcg"]
    assert [ln.split(":")[0] for ln in f.lines] == ["host", "uml", "qemu-kvm"]
    assert all(ln.endswith("; trying " + nxt) for ln, nxt in zip(f.lines, ["uml", "qemu-kvm", "qemu-tcg"]))
    assert "ptrace set fp regs failed, errno = 14" in f.lines[1]
    assert res.notes == ["uml: " + panic().reason]


def test_no_backend_names_every_reason_in_order():
    f = Backends(unusable={"host": "no CAN (fake)", "qemu-kvm": "no /dev/kvm (fake)",
                           "qemu-tcg": "qemu-system-x86_64 not found (fake)"},
                 boots={"uml": panic()})
    with pytest.raises(choice.VcanError) as e:
        f.run("auto")
    msg = str(e.value)
    assert msg.startswith("no backend could run the command: host: not usable: no CAN (fake) | uml: ")
    assert msg.index("uml:") < msg.index("qemu-kvm: not usable: no /dev/kvm") < msg.index("qemu-tcg: not usable")
    assert "; trying" not in f.lines[-1] and len(f.lines) == 4


def test_a_failure_after_the_command_started_is_not_retried_elsewhere():
    late = choice.BackendError("uml", "timed out after 5 s while running the command", boot_failed=False)
    f = Backends(unusable={"host": "no CAN"}, boots={"uml": late})
    with pytest.raises(choice.BackendError, match="^uml: timed out after 5 s while running"):
        f.run("auto")
    assert f.attempted == ["uml"]


def test_a_forced_backend_gives_its_own_reason_and_no_fallback():
    f = Backends(unusable={"qemu-kvm": "the CPU has no vmx/svm flag (fake)"}, boots={"uml": panic()})
    with pytest.raises(choice.VcanError, match=r"^qemu-kvm: not usable: the CPU has no vmx/svm flag"):
        f.run("qemu-kvm")
    with pytest.raises(choice.VcanError, match=r"^uml: .*ptrace set fp regs failed"):
        f.run("uml")
    assert f.attempted == ["uml"] and f.lines == []


def test_a_backend_that_failed_is_not_booted_again_by_a_fallback():
    failed = {}
    f = Backends(unusable={"host": "no CAN"}, boots={"uml": panic()})
    assert f.run("auto", failed).mode == "qemu-kvm"
    assert f.run("auto", failed).mode == "qemu-kvm"
    assert f.attempted == ["uml", "qemu-kvm", "qemu-kvm"] and set(failed) == {"uml"}
    with pytest.raises(choice.VcanError):       # forced: tried again, whatever happened before
        f.run("uml", failed)
    assert f.attempted[-1] == "uml"


# ---------------------------------------------------------------------------------------------
# KVM pre-check
# ---------------------------------------------------------------------------------------------
def test_cpu_flags_from_cpuinfo():
    assert "amx_tile" in choice.parse_cpu_flags(CPUINFO_AMX)
    assert choice.parse_cpu_flags(CPUINFO_EPYC) == {"fpu", "sse", "xsave", "avx"}
    assert choice.parse_cpu_flags("") == set()


@pytest.mark.parametrize("cpuinfo, exists, rw, check, expected", [
    (CPUINFO_VMX, True, True, True, None),
    (CPUINFO_AMX, True, True, True, "the CPU has no vmx/svm flag (/dev/kvm exists)"),
    (CPUINFO_EPYC, True, True, False, None),                 # tried anyway: what does it do?
    (CPUINFO_VMX, False, False, True, "no /dev/kvm (kvm module not loaded)"),
    (CPUINFO_EPYC, False, False, False, "no /dev/kvm (kvm module not loaded)"),
    (CPUINFO_VMX, True, False, True, "/dev/kvm is not accessible to this user (group kvm)"),
])
def test_kvm_precheck(cpuinfo, exists, rw, check, expected):
    assert choice.kvm_precheck(choice.parse_cpu_flags(cpuinfo), exists, rw, check) == expected


# ---------------------------------------------------------------------------------------------
# The XSTATE wrapper: the kernel's answer decides
# ---------------------------------------------------------------------------------------------
def probe_of(host_bytes, err):
    """xstate_selftest --probe's output on a host of that XSAVE size whose kernel answers err."""
    return lambda: choice.parse_probe(0, f"probe_bytes=2696 host_bytes={host_bytes} errno={err}\n", "")


def never():
    raise AssertionError("the probe must not run here")


def test_probe_output_parsed():
    p = choice.parse_probe(0, "probe_bytes=2696 host_bytes=11008 errno=14\n", "")
    assert p.errno == errno.EFAULT and "refused it with errno 14 (EFAULT)" in p.detail and "11008" in p.detail
    p = choice.parse_probe(0, "probe_bytes=2696 host_bytes=2440 errno=0\n", "")
    assert p.errno == 0 and "accepted it" in p.detail and "2440" in p.detail
    p = choice.parse_probe(2, "", "xstate_selftest: the child did not stop under ptrace\n")
    assert p.errno is None and p.detail.endswith("the child did not stop under ptrace")
    p = choice.parse_probe(None, "", "no C compiler (cc/gcc) to build the XSTATE wrapper")
    assert p.errno is None and "no C compiler" in p.detail
    assert choice.parse_probe(0, "garbage", "").errno is None


@pytest.mark.parametrize("machine, host_bytes, err, first, retry", [
    ("Xeon with AMX", 11008, errno.EFAULT, "auto", False),   # the kernel refuses UML's write
    ("AMD EPYC, no AVX-512", 2440, 0, None, True),            # smaller area: the kernel takes its part
    ("AMD EPYC with AVX-512", 2432, 0, None, True),
    ("AVX-512 and PKRU", 2696, 0, None, True),                # UML's own size
    ("a refusal of another kind", 2696, errno.EPERM, None, True),
])
def test_wrapper_plan_follows_the_kernel(machine, host_bytes, err, first, retry):
    plan = choice.wrapper_plan("auto", (6, 1, 176), probe_of(host_bytes, err))
    assert (plan.first, plan.retry) == (first, retry), machine
    assert str(host_bytes) in plan.why


def test_wrapper_plan_when_the_probe_cannot_run_or_is_not_needed():
    plan = choice.wrapper_plan("auto", (), lambda: choice.parse_probe(None, "", "no C compiler"))
    assert plan.first is None and plan.retry and "no C compiler" in plan.why
    plan = choice.wrapper_plan("auto", (6, 13, 0), never)
    assert plan.first is None and "sizes its XSTATE buffer at run time" in plan.why


@pytest.mark.parametrize("setting, first, retry", [("off", None, False), ("on", "auto", False),
                                                   ("full", "full", False)])
def test_wrapper_plan_forced(setting, first, retry):
    plan = choice.wrapper_plan(setting, (6, 1, 176), never)
    assert (plan.first, plan.retry) == (first, retry) and setting in plan.why


def test_xstate_setting_checked():
    assert choice.xstate_setting(None) == "auto" and choice.xstate_setting(" FULL ") == "full"
    assert choice.xstate_setting("") == "auto"
    with pytest.raises(ValueError, match="ATTEKF_UML_XSTATE must be one of"):
        choice.xstate_setting("yes")


def test_retry_only_after_the_panic_of_a_boot_without_the_wrapper():
    plan = choice.wrapper_plan("auto", (6, 1, 176), probe_of(2440, 0))
    assert choice.retry_with_wrapper(plan, panic())
    other = choice.BackendError("uml", "the guest did not report a status (exit 0): vcan_run (guest): "
                                       "insmod net/can/can.ko", evidence="vcan_run (guest): insmod net/can/can.ko")
    assert not choice.retry_with_wrapper(plan, other)
    late = choice.BackendError("uml", "timed out", boot_failed=False, evidence=UML_PANIC)
    assert not choice.retry_with_wrapper(plan, late)
    wrapped = choice.wrapper_plan("auto", (6, 1, 176), probe_of(11008, errno.EFAULT))
    assert not choice.retry_with_wrapper(wrapped, panic())
    off = choice.wrapper_plan("off", (6, 1, 176), never)
    assert not choice.retry_with_wrapper(off, panic())


# ---------------------------------------------------------------------------------------------
# Root cause and outcome of a finished guest
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("texts, expected", [
    ((UML_PANIC,), "userspace - ptrace set fp regs failed, errno = 14; "
                   "Kernel panic - not syncing: Attempted to kill init! exitcode=0x0000000b"),
    (("", "", QEMU_MSR), "qemu-system-x86_64: error: failed to set MSR 0x10a to 0x69"),
    (("vcan_run (guest): insmod drivers/net/can/vcan.ko",), "vcan_run (guest): insmod drivers/net/can/vcan.ko"),
    (("[ 1.2] VFS: Unable to mount root fs on unknown-block(0,0)\n[ 1.2] Kernel panic - not syncing: VFS\n",),
     "VFS: Unable to mount root fs on unknown-block(0,0); Kernel panic - not syncing: VFS"),
    (("Linux version 6.1\nRun /init as init process\n",), ""),
])
def test_root_cause(texts, expected):
    assert choice.root_cause(*texts) == expected


def boot(rc=0, seconds=2.0, started=1.0, timed_out=False, silent=False):
    return choice.Boot(returncode=rc, seconds=seconds, boot_seconds=started, timed_out=timed_out,
                       marker_missing=silent)


def test_outcome_of_a_guest_that_ran_the_command():
    res = choice.outcome("uml", boot(), choice.GuestFiles(status="3\n", stdout="out", stderr="err",
                                                          console="c", started=True), 60)
    assert (res.returncode, res.stdout, res.stderr, res.mode, res.boot_seconds) == (3, "out", "err", "uml", 1.0)
    res = choice.outcome("uml", boot(), choice.GuestFiles(status="x", started=True), 60)
    assert res.returncode == choice.EXIT_INFRA


def test_outcome_of_a_silent_guest():
    with pytest.raises(choice.BackendError) as e:
        choice.outcome("qemu-kvm", boot(rc=None, seconds=6.1, started=0.0, silent=True), choice.GuestFiles(), 60)
    assert e.value.boot_failed and e.value.cause == ""
    assert e.value.reason == "the guest printed nothing on its console in 6.1 s (hangs before the kernel's first message)"


def test_outcome_of_an_emulator_that_fails_at_once():
    with pytest.raises(choice.BackendError) as e:
        choice.outcome("qemu-kvm", boot(rc=-6, seconds=0.3, started=0.0), choice.GuestFiles(extra=QEMU_MSR), 60)
    assert e.value.boot_failed
    assert e.value.reason == "the guest did not report a status (exit -6): qemu-system-x86_64: error: failed to set MSR 0x10a to 0x69"
    assert e.value.cause in e.value.evidence


def test_outcome_of_a_panic_and_of_a_failed_set_up():
    with pytest.raises(choice.BackendError) as e:
        choice.outcome("uml", boot(rc=-6, started=0.0), choice.GuestFiles(console=UML_PANIC), 60)
    assert "ptrace set fp regs failed, errno = 14" in e.value.reason and "Kernel panic" in e.value.reason
    assert e.value.boot_failed and e.value.evidence.count("ptrace set fp regs failed") == 1
    files = choice.GuestFiles(status="125\n", setup="vcan_run (guest): create vcan0\n")
    with pytest.raises(choice.BackendError, match=r"exit 0\): vcan_run \(guest\): create vcan0"):
        choice.outcome("uml", boot(started=0.0), files, 60)
    with pytest.raises(choice.BackendError, match=r"console tail: 'booting'"):
        choice.outcome("uml", boot(started=0.0), choice.GuestFiles(console="booting\n"), 60)


def test_outcome_of_a_timeout_before_and_after_the_command_started():
    with pytest.raises(choice.BackendError) as e:
        choice.outcome("qemu-tcg", boot(rc=None, started=0.0, timed_out=True),
                       choice.GuestFiles(console="[ 3.0] 9pnet_virtio: no channels available for device hostroot\n"), 30)
    assert e.value.boot_failed and e.value.reason.startswith("timed out after 30 s before the command started")
    with pytest.raises(choice.BackendError) as e:
        choice.outcome("qemu-tcg", boot(rc=None, timed_out=True), choice.GuestFiles(started=True), 30)
    assert not e.value.boot_failed and e.value.reason == "timed out after 30 s while running the command"
