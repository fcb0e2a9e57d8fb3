"""What the vcan backends of hal/tools/vcan_run.py share: the result and error types, the
guest's init script, the work directory, the wait for a booting guest, and the search of a
guest console for the line that says why a boot failed.

A guest (user-mode Linux or QEMU) sees the host's files at the same paths; the init script
runs the command in the caller's directory with the caller's environment and sends its
stdout, stderr and exit status back through files in a per-run work directory. It writes
``started`` there just before the command, so the host can tell "the guest did not boot"
(try another backend) from "the command failed" (report it).

Standard library only."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import signal
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Union

EXIT_INFRA = 125          # could not run the command at all
# Environment variables not passed into a guest (meaningless or harmful there).
_ENV_SKIP = {"TERM", "TERMCAP", "COLUMNS", "LINES", "SHLVL", "_", "OLDPWD", "PWD",
             "SSH_AUTH_SOCK", "SSH_CONNECTION", "SSH_CLIENT", "SSH_TTY", "DISPLAY", "LD_PRELOAD"}
PATH_GUEST = "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"


class VcanError(RuntimeError):
    """The command could not be run (no backend, boot failure, timeout)."""


class BackendError(VcanError):
    """One backend could not run the command. boot_failed: it never reached the command
    (trying the next backend makes sense); reason: the root cause in one line."""

    def __init__(self, backend: str, reason: str, boot_failed: bool = True, console: str = ""):
        super().__init__(f"{backend}: {reason}")
        self.backend = backend
        self.reason = reason
        self.boot_failed = boot_failed
        self.console = console


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


def as_shell(cmd: Union[str, Sequence[str]]) -> str:
    return cmd if isinstance(cmd, str) else " ".join(shlex.quote(c) for c in cmd)


def read_text(path: str) -> str:
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            return fh.read()
    except (FileNotFoundError, NotADirectoryError):
        return ""


def cache_dir() -> str:
    """The project's cache of built and downloaded things ($ATTEKF_CACHE_DIR, else
    $XDG_CACHE_HOME/attekf, else ~/.cache/attekf)."""
    d = os.environ.get("ATTEKF_CACHE_DIR")
    if not d:
        d = os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "attekf")
    return d


def find_tool(name: str) -> Optional[str]:
    for cand in (shutil.which(name), f"/usr/sbin/{name}", f"/sbin/{name}"):
        if cand and os.access(cand, os.X_OK):
            return cand
    return None


def cpu_flags() -> set:
    for line in read_text("/proc/cpuinfo").splitlines():
        if line.startswith("flags"):
            return set(line.split(":", 1)[1].split())
    return set()


class WorkDir:
    """A fresh directory shared with the guest (guests booted in parallel share the host's
    files: each run has its own)."""

    def __init__(self, keep: bool):
        self.path = tempfile.mkdtemp(prefix="vcan_run.")
        os.chmod(self.path, 0o755)
        self.keep = keep

    def file(self, name: str) -> str:
        return os.path.join(self.path, name)

    def read(self, name: str) -> str:
        return read_text(self.file(name))

    def close(self) -> None:
        if not self.keep:
            shutil.rmtree(self.path, ignore_errors=True)


def init_script(work: str, cmd: str, ifaces: Sequence[str], env: Dict[str, str], cwd: str,
                prologue: Sequence[str], off: str) -> str:
    """The guest's init: prologue (the backend's mounts and modules), the interfaces, the
    caller's environment and directory, the command, its status; off is the body of the shell
    function that powers the guest off with the status in $1."""
    q = shlex.quote
    lines = [
        "#!/bin/sh",
        "# init of a vcan guest written by hal/tools/vcan_run.py",
        f"PATH={PATH_GUEST}; export PATH",
        f"W={q(work)}",
        f"off() {{ {off}; }}",
        "fail() { echo \"vcan_run (guest): $*\" >> \"$W/setup.log\"; echo 125 > \"$W/status\"; "
        "sync; off 125; }",
    ]
    lines += list(prologue)
    lines.append("ip link set lo up >> \"$W/setup.log\" 2>&1")
    for name in ifaces:
        lines.append(f"ip link add dev {q(name)} type vcan >> \"$W/setup.log\" 2>&1 "
                     f"&& ip link set up {q(name)} >> \"$W/setup.log\" 2>&1 || fail 'create {name}'")
    for k, v in sorted(env.items()):
        if k in _ENV_SKIP or not k.replace("_", "a").isalnum() or k[0].isdigit():
            continue
        lines.append(f"{k}={q(v)}; export {k}")
    lines += [
        f"cd {q(cwd)} || fail 'cd {cwd}'",
        "cat /proc/uptime > \"$W/started\"",
        f"/bin/sh -c {q(cmd)} > \"$W/stdout\" 2> \"$W/stderr\" < /dev/null",
        "rc=$?",
        "echo $rc > \"$W/status\"",
        "sync",
        "off $rc",
    ]
    return "\n".join(lines) + "\n"


@dataclass
class Boot:
    returncode: Optional[int]   # the backend process's exit status (None: killed)
    seconds: float
    boot_seconds: float         # until `started` appeared (0 if it never did)
    timed_out: bool
    marker_missing: bool        # no console output within marker_s


def run_guest(argv: List[str], work: WorkDir, timeout: float, env: Optional[Dict[str, str]] = None,
              output: str = "console.log", watch: Optional[str] = None,
              marker_s: Optional[float] = None) -> Boot:
    """Starts a guest (its stdout and stderr to the work directory's `output`) and waits for it
    to end, watching for `started` in the work directory. marker_s: kill the guest if the
    console file `watch` (default `output`) is still empty after that many seconds (a guest
    that hangs before printing anything)."""
    t0 = time.monotonic()
    console = work.file(watch or output)
    boot_s = 0.0
    with open(work.file(output), "ab") as out:
        p = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                             cwd=work.path, start_new_session=True, env=env)
    started = work.file("started")
    timed_out = marker_missing = False
    while True:
        try:
            p.wait(timeout=0.05)
            break
        except subprocess.TimeoutExpired:
            pass
        now = time.monotonic() - t0
        if not boot_s and os.path.exists(started):
            boot_s = now
        if marker_s is not None and now > marker_s and not boot_s:
            try:
                marker_missing = os.path.getsize(console) == 0
            except OSError:
                marker_missing = True
        if now > timeout or marker_missing:
            timed_out = not marker_missing
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            p.wait()
            break
    seconds = time.monotonic() - t0
    if not boot_s and os.path.exists(started):
        boot_s = seconds
    return Boot(returncode=None if (timed_out or marker_missing) else p.returncode,
                seconds=seconds, boot_seconds=boot_s, timed_out=timed_out, marker_missing=marker_missing)


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


def finish(work: WorkDir, boot: Boot, backend: str, timeout: float, console: str,
           extra: str = "") -> Result:
    """Turns a finished guest into a Result, or a BackendError naming the root cause."""
    status = work.read("status").strip()
    setup = work.read("setup.log").strip()
    started = bool(boot.boot_seconds) or os.path.exists(work.file("started"))
    if boot.marker_missing:
        raise BackendError(backend, f"the guest printed nothing on its console in {boot.seconds:.1f} s "
                                    f"(hangs before the kernel's first message)", console=console)
    if boot.timed_out:
        where = "while running the command" if started else "before the command started"
        cause = root_cause(setup, console, extra)
        raise BackendError(backend, f"timed out after {timeout:g} s {where}"
                           + (f" ({cause})" if cause else ""), boot_failed=not started, console=console)
    if not status or (status == str(EXIT_INFRA) and "vcan_run (guest)" in setup):
        cause = root_cause(setup, console, extra) or f"console tail: {console.strip()[-300:]!r}"
        raise BackendError(backend, f"the guest did not report a status (exit {boot.returncode}): {cause}",
                           boot_failed=not started, console=console)
    return Result(returncode=int(status) if status.lstrip("-").isdigit() else EXIT_INFRA,
                  stdout=work.read("stdout"), stderr=work.read("stderr"), mode=backend,
                  seconds=boot.seconds, console=console, boot_seconds=boot.boot_seconds)
