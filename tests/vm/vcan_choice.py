"""The decisions of the vcan runner (vcan_run.py), as pure logic: which backends a mode tries
and in which order, the fallback from one to the next, whether user-mode Linux needs the
ptrace XSTATE wrapper and whether a failed boot is retried with it, whether KVM is worth a
try, and how a finished guest becomes a result or a one-line root cause.

Nothing here starts a process or reads a file: the callers pass in what the machine, the
kernel and the guests did (CPU flags, the kernel's answer to a probe, a guest's console and
exit status), so every branch is tested with fakes on any machine
(tests/python/hil/test_vcan_choice.py). The same root situation shows differently on
different CPUs (docs/hil.md, "Machines seen"), so no decision here is taken from a CPU model
or a size comparison alone: the wrapper from the kernel's answer to UML's own write, KVM from
what its guest does within a few seconds.

Standard library only."""

from __future__ import annotations

import errno as errno_codes
import re
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence, Tuple

BACKENDS = ("host", "uml", "qemu-kvm", "qemu-tcg")
MODES = ("auto",) + BACKENDS + ("qemu",)
EXIT_INFRA = 125          # could not run the command at all

# user-mode Linux before 6.13 moves its guests' FPU state with ptrace(NT_X86_XSTATE) on a
# buffer sized when it was built (Debian bookworm's 6.1: these bytes, seen in the wrapper's
# log); 6.13 sizes it from the host's CPUID at run time.
UML_XSTATE_BYTES = 2696
UML_XSTATE_FIXED_IN = (6, 13)
FP_REGS_FAILED = "ptrace set fp regs failed"      # UML's console line when the host refuses
XSTATE_SETTINGS = ("auto", "on", "full", "off")


class VcanError(RuntimeError):
    """The command could not be run (no backend, boot failure, timeout)."""


class BackendError(VcanError):
    """One backend could not run the command.

    boot_failed: it never reached the command (trying the next backend makes sense);
    reason: one line, the root cause included; cause: the guest's own line(s) that say why
    ('' when it showed none, e.g. a guest that printed nothing); evidence: everything the
    guest showed (console, set-up log, emulator's messages), which the cause comes from."""

    def __init__(self, backend: str, reason: str, boot_failed: bool = True, console: str = "",
                 cause: str = "", evidence: str = ""):
        super().__init__(f"{backend}: {reason}")
        self.backend = backend
        self.reason = reason
        self.boot_failed = boot_failed
        self.console = console
        self.cause = cause
        self.evidence = evidence or console


@dataclass
class Result:
    returncode: int
    stdout: str
    stderr: str
    mode: str             # backend: "host", "uml", "qemu-kvm" or "qemu-tcg"
    seconds: float        # wall time, boot included
    console: str = ""     # the guest's console (kernel messages), for diagnosing
    boot_seconds: float = 0.0            # start of the backend to the command's start
    notes: List[str] = field(default_factory=list)   # fallbacks and adaptations, one line each


# ---------------------------------------------------------------------------------------------
# Which backends, in which order
# ---------------------------------------------------------------------------------------------
def order(mode: str) -> Tuple[List[str], bool]:
    """Backends to try for a mode, and whether falling back between them is allowed."""
    if mode == "auto":
        return list(BACKENDS), True
    if mode == "qemu":
        return ["qemu-kvm", "qemu-tcg"], True
    if mode in BACKENDS:
        return [mode], False
    raise ValueError(f"mode must be one of {', '.join(MODES)}, not {mode!r}")


def first_working(backends: Sequence[str], fallback: bool, precheck: Callable[[str], Optional[str]],
                  attempt: Callable[[str], Result], failed: Dict[str, str],
                  log: Callable[[str], None]) -> Result:
    """Runs the command on the first backend that can.

    precheck(b): why b cannot be used here, found without booting (None: try it);
    attempt(b): the Result, or BackendError; failed: backend -> why its boot failed earlier in
    this process (a fallback does not try it again; updated here); log: one line per backend
    given up, with its reason and the next one tried. Raises VcanError: a forced backend's
    own reason, a failure after the command started (not retried: the command may have had
    effects), or every backend's reason."""
    reasons: List[str] = []
    notes: List[str] = []
    for i, b in enumerate(backends):
        nxt = f"; trying {backends[i + 1]}" if i + 1 < len(backends) else ""
        if fallback and b in failed:
            reasons.append(f"{b}: {failed[b]}")
            continue
        why = precheck(b)
        if why:
            if not fallback:
                raise BackendError(b, f"not usable: {why}")
            reasons.append(f"{b}: not usable: {why}")
            log(f"{b}: not usable: {why}{nxt}")
            continue
        try:
            res = attempt(b)
        except BackendError as e:
            if not fallback or not e.boot_failed:
                raise
            failed[b] = e.reason
            reasons.append(f"{b}: {e.reason}")
            notes.append(f"{b}: {e.reason}")
            log(f"{b}: {e.reason}{nxt}")
            continue
        res.notes = notes + res.notes
        return res
    raise VcanError("no backend could run the command: " + " | ".join(reasons))


def kvm_precheck(cpu_flags: Sequence[str], dev_exists: bool, dev_rw: bool,
                 check_flags: bool = True) -> Optional[str]:
    """Why a KVM guest is not worth a try here, or None. check_flags=False tries KVM even on
    a CPU without vmx/svm (to see what the emulator does there)."""
    if not dev_exists:
        return "no /dev/kvm (kvm module not loaded)"
    if not dev_rw:
        return "/dev/kvm is not accessible to this user (group kvm)"
    if check_flags and not ({"vmx", "svm"} & set(cpu_flags)):
        return "the CPU has no vmx/svm flag (/dev/kvm exists)"
    return None


def parse_cpu_flags(cpuinfo: str) -> set:
    """The flags of the first processor in /proc/cpuinfo's text."""
    for line in cpuinfo.splitlines():
        if line.startswith("flags"):
            return set(line.split(":", 1)[1].split())
    return set()


# ---------------------------------------------------------------------------------------------
# user-mode Linux: the XSTATE wrapper
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Probe:
    """The host kernel's answer to an NT_X86_XSTATE write of UML's buffer size to a stopped
    child (uml_xstate/xstate_selftest --probe). errno: 0 accepted, else the kernel's errno;
    None: the probe could not run. detail: one line saying what was tried and seen."""
    errno: Optional[int]
    detail: str


def parse_probe(returncode: Optional[int], stdout: str, stderr: str) -> Probe:
    """xstate_selftest --probe's output as a Probe."""
    m = re.search(r"probe_bytes=(\d+) host_bytes=(\d+) errno=(\d+)", stdout)
    if returncode != 0 or not m:
        why = (stderr.strip().splitlines() or [f"exit {returncode}, no answer"])[-1]
        return Probe(None, f"the XSTATE probe could not run: {why}")
    n, host, e = (int(x) for x in m.groups())
    said = "accepted it" if e == 0 else f"refused it with errno {e} ({errno_codes.errorcode.get(e, '?')})"
    return Probe(e, f"the host kernel {said} (an XSTATE write of {n} bytes to a stopped child; "
                    f"its XSAVE area: {host} bytes)")


@dataclass(frozen=True)
class WrapperPlan:
    """first: the wrapper's mode for the first boot (None: without it, "auto", "full");
    retry: a boot without it that fails with UML's FP_REGS_FAILED panic is retried with it;
    why: one line."""
    first: Optional[str]
    retry: bool
    why: str


def xstate_setting(value: Optional[str]) -> str:
    """$ATTEKF_UML_XSTATE checked (unset or empty: auto)."""
    s = (value or "auto").strip().lower() or "auto"
    if s not in XSTATE_SETTINGS:
        raise ValueError(f"ATTEKF_UML_XSTATE must be one of {', '.join(XSTATE_SETTINGS)}, not {s!r}")
    return s


def wrapper_plan(setting: str, uml_version: Tuple[int, ...], probe: Callable[[], Probe]) -> WrapperPlan:
    """Whether UML boots with the XSTATE wrapper. setting: $ATTEKF_UML_XSTATE; uml_version:
    () when linux.uml did not say; probe: asks the host kernel (called only when needed).

    auto: the wrapper when the kernel refuses a write of UML's size with EFAULT (what makes
    UML panic); without it when the kernel accepts the write (a host XSAVE area of UML's size
    or smaller: the kernel takes the part it needs), when UML sizes its buffer at run time, or
    when the probe cannot tell; in those cases the panic, if it comes, is retried with it."""
    if setting == "off":
        return WrapperPlan(None, False, "XSTATE wrapper off (ATTEKF_UML_XSTATE=off)")
    if setting in ("on", "full"):
        mode = "full" if setting == "full" else "auto"
        return WrapperPlan(mode, False, f"XSTATE wrapper forced (ATTEKF_UML_XSTATE={setting})")
    vs = ".".join(map(str, uml_version)) or "of unknown version"
    if uml_version and uml_version[:2] >= UML_XSTATE_FIXED_IN:
        return WrapperPlan(None, True, f"XSTATE wrapper not needed: UML {vs} sizes its XSTATE buffer at run time")
    p = probe()
    if p.errno == errno_codes.EFAULT:
        return WrapperPlan("auto", False, f"XSTATE wrapper used: UML {vs} writes {UML_XSTATE_BYTES} bytes "
                                          f"and {p.detail}")
    if p.errno == 0:
        return WrapperPlan(None, True, f"XSTATE wrapper not needed: UML {vs} writes {UML_XSTATE_BYTES} "
                                       f"bytes and {p.detail}")
    return WrapperPlan(None, True, f"XSTATE wrapper not chosen in advance ({p.detail}); "
                                   "a boot that panics on it is retried with it")


def retry_with_wrapper(plan: WrapperPlan, err: BackendError) -> bool:
    """Whether a failed UML boot is tried again with the wrapper: the plan allows it (only a
    plan whose first boot is without it does) and the guest died on the host's refusal of its
    XSTATE write before the command started."""
    return plan.retry and err.boot_failed and FP_REGS_FAILED in err.evidence


# ---------------------------------------------------------------------------------------------
# A finished guest: its result, or why it failed
# ---------------------------------------------------------------------------------------------
# Lines of guest output that say why a guest died, most specific first; the kernel's panic
# line, when there is one, is added after the cause.
_CAUSES = [
    re.compile(r"[^\n]*ptrace set fp regs failed[^\n]*"),
    re.compile(r"[^\n]*ptrace [^\n]* failed[^\n]*"),
    re.compile(r"vcan_run \(guest\):[^\n]*"),
    re.compile(r"VFS: Unable to mount[^\n]*"),
    re.compile(r"[^\n]*(?:mount|insmod|switch_root)[^\n]*(?:failed|No such|Invalid|error)[^\n]*", re.I),
    re.compile(r"qemu-system-\w+: [^\n]*"),
    re.compile(r"Failed to execute [^\n]*|BUG: [^\n]*|Oops: [^\n]*"),
]
_PANIC = re.compile(r"Kernel panic - not syncing: [^\n]*")


def root_cause(*texts: str) -> str:
    """The line of guest output that says why it failed, and the kernel's panic line when
    there is one; '' if nothing matched."""
    text = "\n".join(t.replace("\r", "") for t in texts if t)
    found: List[str] = []
    for pat in _CAUSES:
        m = pat.search(text)
        if m:
            found.append(re.sub(r"^\[ *[0-9.]+\] ", "", m.group(0).strip()))
            break
    m = _PANIC.search(text)
    if m:
        found.append(m.group(0).strip())
    return "; ".join(found)


@dataclass
class Boot:
    """How the guest's process ended (vcan_guest.run_guest)."""
    returncode: Optional[int]   # the backend process's exit status (None: killed)
    seconds: float
    boot_seconds: float         # until the command started (0 if it never did)
    timed_out: bool
    marker_missing: bool        # killed: nothing on the console within the marker time


@dataclass
class GuestFiles:
    """What the guest left in its work directory, and what it printed."""
    status: str = ""      # the command's exit status, written by the init script
    setup: str = ""       # the init script's set-up log (modules, interfaces)
    console: str = ""     # the guest kernel's console
    extra: str = ""       # the emulator's own messages (QEMU's stderr)
    stdout: str = ""
    stderr: str = ""
    started: bool = False  # the init script reached the command


def outcome(backend: str, boot: Boot, files: GuestFiles, timeout: float) -> Result:
    """A finished guest as a Result, or a BackendError with the root cause it showed."""
    evidence = "\n".join(t for t in (files.setup, files.console, files.extra) if t)
    started = bool(boot.boot_seconds) or files.started
    if boot.marker_missing:
        raise BackendError(backend, f"the guest printed nothing on its console in {boot.seconds:.1f} s "
                                    "(hangs before the kernel's first message)",
                           console=files.console, evidence=evidence)
    cause = root_cause(files.setup, files.console, files.extra)
    if boot.timed_out:
        where = "while running the command" if started else "before the command started"
        raise BackendError(backend, f"timed out after {timeout:g} s {where}" + (f" ({cause})" if cause else ""),
                           boot_failed=not started, console=files.console, cause=cause, evidence=evidence)
    status = files.status.strip()
    if not status or (status == str(EXIT_INFRA) and "vcan_run (guest)" in files.setup):
        shown = cause or f"console tail: {files.console.strip()[-300:]!r}"
        raise BackendError(backend, f"the guest did not report a status (exit {boot.returncode}): {shown}",
                           boot_failed=not started, console=files.console, cause=cause, evidence=evidence)
    return Result(returncode=int(status) if status.lstrip("-").isdigit() else EXIT_INFRA,
                  stdout=files.stdout, stderr=files.stderr, mode=backend, seconds=boot.seconds,
                  console=files.console, boot_seconds=boot.boot_seconds)
