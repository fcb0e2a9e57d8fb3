"""The user-mode Linux backend of vcan_run.py (docs/hil.md).

Debian's ``linux.uml`` boots with the host's ``/`` as its root file system (hostfs) in about
2 s and loads the ``can``, ``can-raw``, ``can-bcm``, ``can-dev`` and ``vcan`` modules shipped
with it. UML kernels before 6.13 move their guests' FPU state with ptrace(NT_X86_XSTATE) in a
buffer sized at build time, which a host kernel refuses to write (EFAULT) when its own XSAVE
area is larger (a CPU with AMX): the first guest process dies with ``ptrace set fp regs
failed, errno = 14`` and the guest panics. Whether this host refuses is asked of the kernel
itself (uml_xstate/xstate_selftest --probe: the same write, to a stopped child of ours); where
it does, the boot runs with the ptrace wrapper of uml_xstate/ preloaded, built from source on
first use into the project's cache. The decision is vcan_choice.wrapper_plan;
$ATTEKF_UML_XSTATE: auto (default: the wrapper where the kernel refuses UML's write, and one
retry with it after that panic), on, full (the wrapper forced through its host-sized path,
which tests it on any CPU), off (never).

Standard library only."""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
from typing import Dict, List, Optional, Sequence, Tuple

import vcan_choice as choice
import vcan_guest as g

UML_KERNEL = "linux.uml"
UML_MODULES = "/usr/lib/uml/modules"
# Load order matters (dependencies); can-bcm is what python-can's send_periodic needs.
UML_MODULE_FILES = ("net/can/can.ko", "net/can/can-raw.ko", "net/can/can-bcm.ko",
                    "drivers/net/can/dev/can-dev.ko", "drivers/net/can/vcan.ko")
XSTATE_SOURCES = ("xstate_ptrace.c", "xstate_selftest.c", "xstate_layout.h")
XSTATE_CFLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wshadow",
                 "-Wdouble-promotion", "-Werror"]

_version: Optional[Tuple[int, ...]] = None
_probe: Optional[choice.Probe] = None


def available() -> Optional[str]:
    """Why UML cannot be used here, or None if it can."""
    if shutil.which(UML_KERNEL) is None and not os.access(UML_KERNEL, os.X_OK):
        return f"{UML_KERNEL} not found (Debian package user-mode-linux)"
    if not os.path.isdir(UML_MODULES) or not os.listdir(UML_MODULES):
        return f"{UML_MODULES}: no UML kernel modules (Debian package user-mode-linux)"
    for tool in ("insmod", "ip"):
        if g.find_tool(tool) is None:
            return f"{tool} not found (Debian packages kmod, iproute2)"
    return None


def version() -> Tuple[int, ...]:
    """linux.uml's kernel version, e.g. (6, 1, 176); () if it does not say."""
    global _version
    if _version is None:
        try:
            out = subprocess.run([UML_KERNEL, "--version"], capture_output=True, text=True,
                                 timeout=20, stdin=subprocess.DEVNULL).stdout
        except (OSError, subprocess.TimeoutExpired):
            out = ""
        m = re.search(r"(\d+)\.(\d+)(?:\.(\d+))?", out)
        _version = tuple(int(x) for x in m.groups() if x is not None) if m else ()
    return _version


# ---------------------------------------------------------------------------------------------
# The XSTATE wrapper: built from source into the cache, keyed by the sources and flags
# ---------------------------------------------------------------------------------------------
def xstate_dir() -> str:
    return os.path.join(os.path.dirname(os.path.abspath(__file__)), "uml_xstate")


def build_xstate_tools() -> Dict[str, str]:
    """Builds (once per source version) the wrapper library and its self-test; returns their
    paths {"lib": ..., "selftest": ...}. Raises RuntimeError with the compiler's message."""
    src = xstate_dir()
    h = hashlib.sha256(" ".join(XSTATE_CFLAGS).encode())
    for name in XSTATE_SOURCES:
        with open(os.path.join(src, name), "rb") as fh:
            h.update(name.encode() + b"\0" + fh.read())
    out = os.path.join(g.cache_dir(), "uml_xstate", h.hexdigest()[:16])
    paths = {"lib": os.path.join(out, "libxstate_ptrace.so"), "selftest": os.path.join(out, "xstate_selftest")}
    if all(os.path.exists(p) for p in paths.values()):
        return paths
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if not cc:
        raise RuntimeError("no C compiler (cc/gcc) to build the XSTATE wrapper (Debian package build-essential)")
    os.makedirs(out, exist_ok=True)
    jobs = [(paths["lib"], ["-fPIC", "-shared", os.path.join(src, "xstate_ptrace.c")]),
            (paths["selftest"], [os.path.join(src, "xstate_selftest.c")])]
    for target, args in jobs:
        tmp = f"{target}.{os.getpid()}.tmp"
        p = subprocess.run([cc, *XSTATE_CFLAGS, *args, "-o", tmp, "-ldl"], capture_output=True, text=True)
        if p.returncode != 0:
            first = next((ln for ln in p.stderr.splitlines() if "error" in ln), p.stderr.strip()[:300])
            raise RuntimeError(f"building {os.path.basename(target)} failed: {first}")
        os.replace(tmp, target)
    return paths


def probe_xstate_write() -> choice.Probe:
    """The host kernel's answer to an XSTATE write of UML's buffer size (asked once per
    process)."""
    global _probe
    if _probe is None:
        try:
            tools = build_xstate_tools()
            p = subprocess.run([tools["selftest"], "--probe", str(choice.UML_XSTATE_BYTES)],
                               capture_output=True, text=True, timeout=20, stdin=subprocess.DEVNULL)
            _probe = choice.parse_probe(p.returncode, p.stdout, p.stderr)
        except (RuntimeError, OSError, subprocess.TimeoutExpired) as e:
            _probe = choice.parse_probe(None, "", str(e))
    return _probe


def xstate_setting() -> str:
    return choice.xstate_setting(os.environ.get("ATTEKF_UML_XSTATE"))


def wrapper_plan() -> choice.WrapperPlan:
    """Whether this UML on this host boots with the wrapper ($ATTEKF_UML_XSTATE, the UML
    version, the kernel's answer to the probe)."""
    return choice.wrapper_plan(xstate_setting(), version(), probe_xstate_write)


# ---------------------------------------------------------------------------------------------
# Boot
# ---------------------------------------------------------------------------------------------
def _boot(cmd: str, ifaces: Sequence[str], timeout: float, env: Dict[str, str], cwd: str, mem: str,
          keep: bool, wrap: Optional[str]) -> choice.Result:
    """One boot; wrap: None, or the wrapper's mode ("auto" or "full")."""
    work = g.WorkDir(keep)
    try:
        prologue = [
            "mount -t proc proc /proc || fail 'mount /proc'",
            "mount -t sysfs sys /sys 2>/dev/null",
            f"M={UML_MODULES}/$(uname -r)/kernel",
        ] + [f"insmod \"$M/{m}\" >> \"$W/setup.log\" 2>&1 || fail 'insmod {m}'" for m in UML_MODULE_FILES]
        # linux.uml exits with what /proc/exitcode holds when the guest halts
        off = "echo $1 > /proc/exitcode; halt -f"
        init = work.file("init.sh")
        with open(init, "w") as fh:
            fh.write(g.init_script(work.path, cmd, ifaces, env, cwd, prologue, off))
        os.chmod(init, 0o755)
        argv = [UML_KERNEL, f"mem={mem}", "root=/dev/root", "rootfstype=hostfs", "rootflags=/", "rw",
                f"init={init}", "con=null", "con0=null,fd:1",
                f"umid=vcan{os.getpid()}x{os.path.basename(work.path)[-8:]}", f"uml_dir={work.path}"]
        penv = dict(os.environ)
        notes: List[str] = []
        if wrap:
            lib = build_xstate_tools()["lib"]
            penv["LD_PRELOAD"] = (lib + " " + penv.get("LD_PRELOAD", "")).strip()
            penv["ATTEKF_XSTATE_WRAP"] = wrap
            penv["ATTEKF_XSTATE_LOG"] = work.file("xstate.log")
        boot = g.run_guest(argv, work, timeout, env=penv)
        if wrap:
            log = work.read("xstate.log").strip()
            notes.append(f"uml: XSTATE wrapper (mode {wrap}): "
                         + (log.splitlines()[-1].split(": ", 2)[-1] if log else "no XSTATE call logged"))
        res = choice.outcome("uml", boot, g.collect(work, boot), timeout)
        res.notes += notes
        return res
    finally:
        work.close()


def run(cmd: str, ifaces: Sequence[str], timeout: float, env: Dict[str, str], cwd: str, mem: str,
        keep: bool, log) -> choice.Result:
    """Runs cmd in a UML guest; raises BackendError when UML cannot run it (reason: the root
    cause, e.g. the console's panic line)."""
    plan = wrapper_plan()
    notes = [f"uml: {plan.why}"]
    try:
        try:
            res = _boot(cmd, ifaces, timeout, env, cwd, mem, keep, plan.first)
        except choice.BackendError as e:
            if not choice.retry_with_wrapper(plan, e):
                raise
            log(f"uml: boot failed without the XSTATE wrapper ({e.reason}); retrying with it")
            notes.append(f"uml: retried with the XSTATE wrapper after: {e.reason}")
            res = _boot(cmd, ifaces, timeout, env, cwd, mem, keep, "auto")
    except RuntimeError as e:            # the wrapper could not be built
        if isinstance(e, choice.VcanError):
            raise
        raise choice.BackendError("uml", f"needs the XSTATE wrapper, which cannot be built: {e}") from e
    res.notes = notes + res.notes
    return res
