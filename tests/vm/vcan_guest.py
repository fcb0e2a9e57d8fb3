"""What the guest backends of vcan_run.py (user-mode Linux, QEMU) share: the guest's init
script, the work directory, the wait for a booting guest and the collection of what it left
behind (turned into a result or a root cause by vcan_choice.outcome).

A guest (user-mode Linux or QEMU) sees the host's files at the same paths; the init script
runs the command in the caller's directory with the caller's environment and sends its
stdout, stderr and exit status back through files in a per-run work directory. It writes
``started`` there just before the command, so the host can tell "the guest did not boot"
(try another backend) from "the command failed" (report it).

Standard library only."""

from __future__ import annotations

import os
import shlex
import shutil
import signal
import subprocess
import tempfile
import time
from typing import Dict, List, Optional, Sequence, Union

from vcan_choice import EXIT_INFRA, Boot, GuestFiles, parse_cpu_flags

# Environment variables not passed into a guest (meaningless or harmful there).
_ENV_SKIP = {"TERM", "TERMCAP", "COLUMNS", "LINES", "SHLVL", "_", "OLDPWD", "PWD",
             "SSH_AUTH_SOCK", "SSH_CONNECTION", "SSH_CLIENT", "SSH_TTY", "DISPLAY", "LD_PRELOAD"}
PATH_GUEST = "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"


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
    return parse_cpu_flags(read_text("/proc/cpuinfo"))


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
        "# init of a vcan guest written by tests/vm/vcan_run.py",
        f"PATH={PATH_GUEST}; export PATH",
        f"W={q(work)}",
        f"off() {{ {off}; }}",
        f"fail() {{ echo \"vcan_run (guest): $*\" >> \"$W/setup.log\"; echo {EXIT_INFRA} > \"$W/status\"; "
        f"sync; off {EXIT_INFRA}; }}",
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


def collect(work: WorkDir, boot: Boot, console: str = "console.log", extra: str = "") -> GuestFiles:
    """What a finished guest left in its work directory (extra: the emulator's own log file)."""
    return GuestFiles(status=work.read("status"), setup=work.read("setup.log").strip(),
                      console=work.read(console), extra=work.read(extra) if extra else "",
                      stdout=work.read("stdout"), stderr=work.read("stderr"),
                      started=bool(boot.boot_seconds) or os.path.exists(work.file("started")))
