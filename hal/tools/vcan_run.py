#!/usr/bin/env python3
"""Run a command on a machine with a virtual CAN interface (vcan0) up, and return its output
and exit status.

Where the running kernel has CAN (``socket(PF_CAN)`` works), the command runs directly, after
creating the interfaces if they are missing (root). Where it has not (these build machines),
the command runs inside user-mode Linux: Debian's ``linux.uml`` boots with the host's ``/`` as
its root file system (hostfs) in about 2 s, loads the ``can``, ``can-raw``, ``can-bcm``,
``can-dev`` and ``vcan`` modules shipped with it, creates the interfaces and runs the command in
the current directory with the current environment. The command's stdout, stderr and exit status
travel back through files on the shared file system (the UML console mixes in kernel messages,
and ``linux.uml`` itself exits 0 whatever happens inside). No TTY is needed (CI has no stdin).

Command line::

    hal/tools/vcan_run.py [--mode auto|host|uml] [--timeout S] [--iface vcan0 ...] -- CMD ARGS...
    hal/tools/vcan_run.py --shell 'candump -n 1 vcan0 & cansend vcan0 123#00; wait'

exits with the command's status (125 if the machine could not run it: no UML, boot failure,
timeout), its stdout/stderr copied to ours. From Python: :func:`run`.

Standard library only (usable before the project's virtual environment exists). Guests booted in
parallel get their own interfaces but share the host's files: every run uses its own temporary
directory.
"""

from __future__ import annotations

import argparse
import errno
import os
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Union

UML_KERNEL = "linux.uml"
UML_MODULES = "/usr/lib/uml/modules"
# Load order matters (dependencies); can-bcm is what python-can's send_periodic needs.
UML_MODULE_FILES = ("net/can/can.ko", "net/can/can-raw.ko", "net/can/can-bcm.ko",
                    "drivers/net/can/dev/can-dev.ko", "drivers/net/can/vcan.ko")
EXIT_INFRA = 125          # could not run the command at all
DEFAULT_TIMEOUT_S = 300.0
DEFAULT_MEM = "512M"
# Environment variables not passed into the guest (meaningless or harmful there).
_ENV_SKIP = {"TERM", "TERMCAP", "COLUMNS", "LINES", "SHLVL", "_", "OLDPWD", "PWD",
             "SSH_AUTH_SOCK", "SSH_CONNECTION", "SSH_CLIENT", "SSH_TTY", "DISPLAY"}


class VcanError(RuntimeError):
    """The command could not be run (no CAN here and no usable UML, boot failure, timeout)."""


@dataclass
class Result:
    returncode: int
    stdout: str
    stderr: str
    mode: str            # "host" or "uml"
    seconds: float       # wall time, boot included
    console: str = ""    # UML console (kernel messages), for diagnosing boot problems


def host_has_can() -> bool:
    """True if this kernel supports PF_CAN raw sockets."""
    if not hasattr(socket, "AF_CAN"):
        return False
    try:
        s = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
    except OSError:
        return False
    s.close()
    return True


def uml_available() -> Optional[str]:
    """Why UML cannot be used here, or None if it can."""
    if shutil.which(UML_KERNEL) is None:
        return f"{UML_KERNEL} not found (install the Debian package user-mode-linux)"
    if not os.path.isdir(UML_MODULES) or not os.listdir(UML_MODULES):
        return f"{UML_MODULES}: no UML kernel modules (package user-mode-linux)"
    for tool in ("insmod", "ip"):
        if shutil.which(tool) is None and not os.path.exists(f"/usr/sbin/{tool}") \
                and not os.path.exists(f"/sbin/{tool}"):
            return f"{tool} not found (packages kmod, iproute2)"
    return None


def _ensure_host_ifaces(ifaces: Sequence[str]) -> None:
    for name in ifaces:
        if not os.path.exists(f"/sys/class/net/{name}"):
            subprocess.run(["modprobe", "vcan"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            r = subprocess.run(["ip", "link", "add", "dev", name, "type", "vcan"],
                               capture_output=True, text=True)
            if r.returncode != 0:
                raise VcanError(f"cannot create {name}: {r.stderr.strip()} (needs root and the vcan module)")
        r = subprocess.run(["ip", "link", "set", "up", name], capture_output=True, text=True)
        if r.returncode != 0:
            with open(f"/sys/class/net/{name}/operstate") as fh:
                if fh.read().strip() not in ("up", "unknown"):
                    raise VcanError(f"cannot bring {name} up: {r.stderr.strip()}")


def _as_shell(cmd: Union[str, Sequence[str]]) -> str:
    return cmd if isinstance(cmd, str) else " ".join(shlex.quote(c) for c in cmd)


def _run_host(cmd, ifaces, timeout, env, cwd) -> Result:
    _ensure_host_ifaces(ifaces)
    t0 = time.monotonic()
    try:
        p = subprocess.run(["/bin/sh", "-c", _as_shell(cmd)], capture_output=True, text=True,
                           timeout=timeout, env=env, cwd=cwd, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired as e:
        raise VcanError(f"timed out after {timeout:g} s") from e
    return Result(p.returncode, p.stdout, p.stderr, "host", time.monotonic() - t0)


def _init_script(work: str, cmd: str, ifaces: Sequence[str], env: Dict[str, str], cwd: str) -> str:
    q = shlex.quote
    lines = [
        "#!/bin/sh",
        "# init of a user-mode Linux guest written by hal/tools/vcan_run.py",
        "PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin; export PATH",
        f"W={q(work)}",
        "fail() { echo \"vcan_run (guest): $*\" >> \"$W/setup.log\"; echo 125 > \"$W/status\"; "
        "echo 125 > /proc/exitcode; halt -f; }",
        "mount -t proc proc /proc || fail 'mount /proc'",
        "mount -t sysfs sys /sys 2>/dev/null",
        f"M={q(UML_MODULES)}/$(uname -r)/kernel",
    ]
    for m in UML_MODULE_FILES:
        lines.append(f"insmod \"$M/{m}\" >> \"$W/setup.log\" 2>&1 || fail 'insmod {m}'")
    lines.append("ip link set lo up >> \"$W/setup.log\" 2>&1")
    for name in ifaces:
        lines.append(f"ip link add dev {q(name)} type vcan >> \"$W/setup.log\" 2>&1 "
                     f"&& ip link set up {q(name)} >> \"$W/setup.log\" 2>&1 || fail 'create {name}'")
    # The host environment, minus what makes no sense in the guest.
    for k, v in sorted(env.items()):
        if k in _ENV_SKIP or not k.replace("_", "a").isalnum() or k[0].isdigit():
            continue
        lines.append(f"{k}={q(v)}; export {k}")
    lines += [
        f"cd {q(cwd)} || fail 'cd {cwd}'",
        f"/bin/sh -c {q(cmd)} > \"$W/stdout\" 2> \"$W/stderr\" < /dev/null",
        "rc=$?",
        "echo $rc > \"$W/status\"",
        "sync",
        # linux.uml exits with what /proc/exitcode holds when the guest halts.
        "echo $rc > /proc/exitcode",
        "halt -f",
    ]
    return "\n".join(lines) + "\n"


def _read(path: str) -> str:
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            return fh.read()
    except FileNotFoundError:
        return ""


def _run_uml(cmd, ifaces, timeout, env, cwd, mem, keep) -> Result:
    why = uml_available()
    if why:
        raise VcanError(f"this kernel has no CAN and user-mode Linux cannot be used: {why}")
    work = tempfile.mkdtemp(prefix="vcan_run.")
    os.chmod(work, 0o755)
    init = os.path.join(work, "init.sh")
    with open(init, "w") as fh:
        fh.write(_init_script(work, _as_shell(cmd), ifaces, env, cwd))
    os.chmod(init, 0o755)
    argv = [UML_KERNEL, f"mem={mem}", "root=/dev/root", "rootfstype=hostfs", "rootflags=/", "rw",
            f"init={init}", "con=null", "con0=null,fd:1", f"umid=vcan{os.getpid()}x{os.path.basename(work)[-8:]}",
            f"uml_dir={work}"]
    t0 = time.monotonic()
    console_path = os.path.join(work, "console.log")
    with open(console_path, "wb") as console:
        p = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=console, stderr=subprocess.STDOUT,
                             cwd=work, start_new_session=True)
        try:
            p.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
            console_text = _read(console_path)
            if not keep:
                shutil.rmtree(work, ignore_errors=True)
            raise VcanError(f"timed out after {timeout:g} s inside user-mode Linux "
                            f"(console tail: {console_text[-400:]!r})")
    seconds = time.monotonic() - t0
    status = _read(os.path.join(work, "status")).strip()
    res = Result(returncode=int(status) if status.lstrip("-").isdigit() else EXIT_INFRA,
                 stdout=_read(os.path.join(work, "stdout")), stderr=_read(os.path.join(work, "stderr")),
                 mode="uml", seconds=seconds, console=_read(console_path))
    setup = _read(os.path.join(work, "setup.log"))
    if not keep:
        shutil.rmtree(work, ignore_errors=True)
    if not status:
        raise VcanError(f"the user-mode Linux guest did not report a status (linux.uml exit "
                        f"{p.returncode}); setup: {setup.strip()[-300:]!r}; console tail: "
                        f"{res.console[-400:]!r}")
    if res.returncode == EXIT_INFRA and "vcan_run (guest)" in setup:
        raise VcanError(f"guest set-up failed: {setup.strip()[-300:]}")
    return res


def run(cmd: Union[str, Sequence[str]], *, ifaces: Sequence[str] = ("vcan0",), mode: str = "auto",
        timeout: float = DEFAULT_TIMEOUT_S, env: Optional[Dict[str, str]] = None,
        cwd: Optional[str] = None, mem: str = DEFAULT_MEM, keep: bool = False) -> Result:
    """Runs cmd (a shell string or an argv list) with the vcan interfaces up.

    mode: "host" (this kernel's CAN), "uml" (user-mode Linux) or "auto" (host if it has CAN,
    else UML; $ATTEKF_VCAN_MODE overrides auto). Raises VcanError if the command could not be
    run; the command's own failure is Result.returncode."""
    env = dict(os.environ if env is None else env)
    cwd = os.path.abspath(cwd or os.getcwd())
    if mode == "auto":
        mode = os.environ.get("ATTEKF_VCAN_MODE", "auto")
    if mode == "auto":
        mode = "host" if host_has_can() else "uml"
    if mode == "host":
        if not host_has_can():
            raise VcanError("this kernel has no CAN support (PF_CAN); use mode uml")
        return _run_host(cmd, ifaces, timeout, env, cwd)
    if mode == "uml":
        return _run_uml(cmd, ifaces, timeout, env, cwd, mem, keep)
    raise ValueError(f"mode must be auto, host or uml, not {mode!r}")


def main(argv: Optional[List[str]] = None) -> int:
    ap = argparse.ArgumentParser(
        prog="vcan_run.py",
        description="Run a command with virtual CAN interfaces up: directly if this kernel has CAN, "
                    "else inside user-mode Linux. Exits with the command's status (125: could not "
                    "run it).")
    ap.add_argument("--mode", choices=("auto", "host", "uml"), default="auto",
                    help="where to run (default auto; $ATTEKF_VCAN_MODE overrides auto)")
    ap.add_argument("--iface", action="append", default=None, metavar="NAME",
                    help="vcan interface to create (repeatable; default vcan0)")
    ap.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT_S, help="seconds (default 300)")
    ap.add_argument("--mem", default=DEFAULT_MEM, help="UML guest memory (default 512M)")
    ap.add_argument("--keep", action="store_true", help="keep the UML work directory (debugging)")
    ap.add_argument("--shell", metavar="CMD", help="a shell command line instead of CMD ARGS")
    ap.add_argument("cmd", nargs=argparse.REMAINDER, help="-- CMD ARGS...")
    args = ap.parse_args(argv)
    cmd: Union[str, List[str]]
    if args.shell is not None:
        cmd = args.shell
    else:
        cmd = args.cmd[1:] if args.cmd[:1] == ["--"] else args.cmd
        if not cmd:
            ap.error("no command given (use -- CMD ARGS... or --shell 'CMD')")
    try:
        res = run(cmd, ifaces=args.iface or ["vcan0"], mode=args.mode, timeout=args.timeout,
                  mem=args.mem, keep=args.keep)
    except VcanError as e:
        print(f"vcan_run: {e}", file=sys.stderr)
        return EXIT_INFRA
    sys.stdout.write(res.stdout)
    sys.stderr.write(res.stderr)
    return res.returncode


if __name__ == "__main__":
    sys.exit(main())
