"""The user-mode Linux backend of hal/tools/vcan_run.py (docs/hil.md).

Debian's ``linux.uml`` boots with the host's ``/`` as its root file system (hostfs) in about
2 s and loads the ``can``, ``can-raw``, ``can-bcm``, ``can-dev`` and ``vcan`` modules shipped
with it. UML kernels before 6.13 move their guests' FPU state with ptrace(NT_X86_XSTATE) in a
buffer sized at build time (2,696 bytes), which a host kernel refuses to write when its own
XSAVE area is larger (11,008 bytes on a CPU with AMX): the first guest process dies with
``ptrace set fp regs failed, errno = 14`` and the guest panics. There the boot runs with the
ptrace wrapper of hal/tools/uml_xstate/ preloaded, built from source on first use into the
project's cache. $ATTEKF_UML_XSTATE: auto (default: the wrapper where the UML version and the
CPU need it, and one retry with it after that console line), on, full (the wrapper forced
through its host-sized path, which tests it on any CPU), off (never).

Standard library only."""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
from typing import Dict, List, Optional, Sequence, Tuple

import vcan_guest as g

UML_KERNEL = "linux.uml"
UML_MODULES = "/usr/lib/uml/modules"
# Load order matters (dependencies); can-bcm is what python-can's send_periodic needs.
UML_MODULE_FILES = ("net/can/can.ko", "net/can/can-raw.ko", "net/can/can-bcm.ko",
                    "drivers/net/can/dev/can-dev.ko", "drivers/net/can/vcan.ko")
# The XSTATE buffer of Debian bookworm's linux.uml 6.1 (its calls, logged by the wrapper).
UML_XSTATE_BYTES = 2696
UML_XSTATE_FIXED_IN = (6, 13)     # sizes the buffer from the host's CPUID at run time
XSTATE_SOURCES = ("xstate_ptrace.c", "xstate_selftest.c", "xstate_layout.h")
XSTATE_CFLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wshadow",
                 "-Wdouble-promotion", "-Werror"]
FP_REGS_FAILED = "ptrace set fp regs failed"
XSTATE_SETTINGS = ("auto", "on", "full", "off")

_version: Optional[Tuple[int, ...]] = None


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


def host_xsave_bytes() -> Optional[int]:
    """This CPU's XSAVE area for ptrace (CPUID leaf 0xD), from the self-test's --info; None
    if it cannot be told (no compiler)."""
    try:
        tools = build_xstate_tools()
        out = subprocess.run([tools["selftest"], "--info"], capture_output=True, text=True, timeout=20).stdout
    except (RuntimeError, OSError, subprocess.TimeoutExpired):
        return None
    m = re.search(r"host_bytes=(\d+)", out)
    return int(m.group(1)) if m else None


def xstate_setting() -> str:
    s = os.environ.get("ATTEKF_UML_XSTATE", "auto").strip().lower() or "auto"
    if s not in XSTATE_SETTINGS:
        raise ValueError(f"ATTEKF_UML_XSTATE must be one of {', '.join(XSTATE_SETTINGS)}, not {s!r}")
    return s


def wrapper_needed() -> Tuple[bool, str]:
    """Whether this UML on this CPU needs the wrapper, and why (one line)."""
    v = version()
    vs = ".".join(map(str, v)) or "of unknown version"
    if v and v[:2] >= UML_XSTATE_FIXED_IN:
        return False, f"UML {vs} sizes its XSTATE buffer at run time"
    n = host_xsave_bytes()
    if n is None:
        amx = "amx_tile" in g.cpu_flags()
        return amx, (f"CPU has AMX (amx_tile), UML {vs} < 6.13" if amx
                     else "XSAVE size unknown (no compiler) and no AMX flag")
    if n == UML_XSTATE_BYTES:
        return False, f"host XSAVE area {n} bytes, the same as UML {vs}'s buffer"
    return True, f"host XSAVE area {n} bytes (CPUID 0xD), UML {vs} < 6.13 writes {UML_XSTATE_BYTES}"


# ---------------------------------------------------------------------------------------------
# Boot
# ---------------------------------------------------------------------------------------------
def _boot(cmd: str, ifaces: Sequence[str], timeout: float, env: Dict[str, str], cwd: str, mem: str,
          keep: bool, wrap: Optional[str]) -> g.Result:
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
        console = work.read("console.log")
        if wrap:
            log = work.read("xstate.log").strip()
            notes.append(f"uml: XSTATE wrapper (mode {wrap}): "
                         + (log.splitlines()[-1].split(": ", 2)[-1] if log else "no XSTATE call logged"))
        res = g.finish(work, boot, "uml", timeout, console)
        res.notes += notes
        return res
    finally:
        work.close()


def run(cmd: str, ifaces: Sequence[str], timeout: float, env: Dict[str, str], cwd: str, mem: str,
        keep: bool, log) -> g.Result:
    """Runs cmd in a UML guest; raises g.BackendError when UML cannot run it (reason: the
    root cause, e.g. the console's panic line)."""
    why = available()
    if why:
        raise g.BackendError("uml", f"not usable: {why}")
    setting = xstate_setting()
    notes: List[str] = []
    if setting == "off":
        wrap = None
    elif setting in ("on", "full"):
        wrap = "full" if setting == "full" else "auto"
    else:
        need, why_need = wrapper_needed()
        wrap = "auto" if need else None
        notes.append(f"uml: XSTATE wrapper {'used' if need else 'not needed'}: {why_need}")
    try:
        try:
            res = _boot(cmd, ifaces, timeout, env, cwd, mem, keep, wrap)
        except g.BackendError as e:
            if not (setting == "auto" and wrap is None and e.boot_failed and FP_REGS_FAILED in e.console):
                raise
            log(f"uml: boot failed without the XSTATE wrapper ({e.reason}); retrying with it")
            notes.append(f"uml: retried with the XSTATE wrapper after: {e.reason}")
            res = _boot(cmd, ifaces, timeout, env, cwd, mem, keep, "auto")
    except RuntimeError as e:            # the wrapper could not be built
        if isinstance(e, g.VcanError):
            raise
        raise g.BackendError("uml", f"needs the XSTATE wrapper, which cannot be built: {e}") from e
    res.notes = notes + res.notes
    return res
