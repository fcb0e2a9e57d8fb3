#!/usr/bin/env python3
"""Run a command on a machine with a virtual CAN interface (vcan0) up, and return its output
and exit status, whatever CAN support this machine's kernel and CPU have (docs/hil.md).

Backends, tried in this order by mode auto:

  host      this kernel's CAN (``socket(PF_CAN)`` works): the command runs directly, after
            the interfaces are created if missing (root)
  uml       user-mode Linux (vcan_uml.py): Debian's ``linux.uml`` with the host's ``/`` as its
            root; on CPUs whose XSAVE area UML < 6.13 cannot handle (AMX) with the ptrace
            XSTATE wrapper of uml_xstate/, and one retry with it after a boot that failed with
            ``ptrace set fp regs failed``
  qemu-kvm  QEMU with KVM (vcan_qemu.py): Debian's kernel, the host's ``/`` over virtio-9p;
            only where the CPU has vmx/svm and the guest prints within a few seconds
  qemu-tcg  the same under emulation

Each backend that cannot run the command logs one line with the root cause on stderr, and the
next one is tried; a backend that failed is not tried again in the same process. The command
runs in the current directory with the current environment; its stdout, stderr and exit status
come back through files (no TTY needed; CI has no stdin).

Command line::

    hal/tools/vcan_run.py [--mode auto|host|uml|qemu|qemu-kvm|qemu-tcg] [--timeout S]
                          [--iface vcan0 ...] -- CMD ARGS...
    hal/tools/vcan_run.py --shell 'candump -n 1 vcan0 & cansend vcan0 123#00; wait'
    hal/tools/vcan_run.py --backends        what each backend needs and whether it has it
    hal/tools/vcan_run.py --prepare         fetch the QEMU guest kernel into the cache

exits with the command's status (125 if no backend could run it, with each backend's reason).
$ATTEKF_VCAN_MODE forces a mode like --mode (qemu: KVM where usable, else TCG). From Python:
:func:`run`.

Standard library only (usable before the project's virtual environment exists)."""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import time
from typing import Dict, List, Optional, Sequence, Tuple, Union

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import vcan_guest  # noqa: E402
import vcan_qemu  # noqa: E402
import vcan_uml  # noqa: E402
from vcan_guest import EXIT_INFRA, BackendError, Result, VcanError  # noqa: E402,F401

BACKENDS = ("host", "uml", "qemu-kvm", "qemu-tcg")
MODES = ("auto",) + BACKENDS + ("qemu",)
DEFAULT_TIMEOUT_S = 300.0
DEFAULT_MEM = "512M"
UML_KERNEL = vcan_uml.UML_KERNEL     # kept for callers of the previous single-file runner
_failed: Dict[str, str] = {}         # backend -> why it failed in this process (auto skips it)


def _log(msg: str) -> None:
    print(f"vcan_run: {msg}", file=sys.stderr, flush=True)


def host_can_reason() -> Optional[str]:
    """Why this kernel cannot do PF_CAN raw sockets, or None if it can."""
    if not hasattr(socket, "AF_CAN"):
        return "this Python has no AF_CAN"
    try:
        s = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
    except OSError as e:
        return f"this kernel has no CAN: socket(PF_CAN): {e}"
    s.close()
    return None


def host_has_can() -> bool:
    """True if this kernel supports PF_CAN raw sockets."""
    return host_can_reason() is None


def uml_available() -> Optional[str]:
    """Why UML cannot be used here, or None if it can."""
    return vcan_uml.available()


def backend_status(ifaces: Sequence[str] = ("vcan0",)) -> Dict[str, Tuple[Optional[str], bool]]:
    """For each backend: (why it cannot be used here, or None; whether it is expected to work
    on a machine set up by scripts/setup.sh). Host CAN and KVM depend on the machine; UML and
    QEMU/TCG are installed by the set-up. No guest is booted."""
    host = host_can_reason()
    if host is None and os.geteuid() != 0:
        missing = [n for n in ifaces if not os.path.exists(f"/sys/class/net/{n}")]
        if missing:
            host = f"{', '.join(missing)} missing and not root (cannot create it)"
    qemu = vcan_qemu.available()
    kvm = qemu or vcan_qemu.kvm_usable()
    return {"host": (host, False),
            "uml": (vcan_uml.available(), True),
            "qemu-kvm": (kvm, vcan_qemu.kvm_usable() is None),
            "qemu-tcg": (qemu, True)}


def _ensure_host_ifaces(ifaces: Sequence[str]) -> None:
    for name in ifaces:
        if not os.path.exists(f"/sys/class/net/{name}"):
            subprocess.run(["modprobe", "vcan"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            r = subprocess.run(["ip", "link", "add", "dev", name, "type", "vcan"],
                               capture_output=True, text=True)
            if r.returncode != 0:
                raise BackendError("host", f"cannot create {name}: {r.stderr.strip()} "
                                           "(needs root and the vcan module)")
        r = subprocess.run(["ip", "link", "set", "up", name], capture_output=True, text=True)
        if r.returncode != 0:
            with open(f"/sys/class/net/{name}/operstate") as fh:
                if fh.read().strip() not in ("up", "unknown"):
                    raise BackendError("host", f"cannot bring {name} up: {r.stderr.strip()}")


def _run_host(cmd: str, ifaces, timeout, env, cwd) -> Result:
    why = host_can_reason()
    if why:
        raise BackendError("host", why)
    _ensure_host_ifaces(ifaces)
    t0 = time.monotonic()
    try:
        p = subprocess.run(["/bin/sh", "-c", cmd], capture_output=True, text=True,
                           timeout=timeout, env=env, cwd=cwd, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired as e:
        raise BackendError("host", f"timed out after {timeout:g} s", boot_failed=False) from e
    return Result(p.returncode, p.stdout, p.stderr, "host", time.monotonic() - t0)


def _run_backend(backend: str, cmd: str, ifaces, timeout, env, cwd, mem, keep) -> Result:
    if backend == "host":
        return _run_host(cmd, ifaces, timeout, env, cwd)
    if backend == "uml":
        return vcan_uml.run(cmd, ifaces, timeout, env, cwd, mem, keep, _log)
    if backend in ("qemu-kvm", "qemu-tcg"):
        return vcan_qemu.run(cmd, ifaces, timeout, env, cwd, keep, backend.split("-")[1])
    raise ValueError(f"mode must be one of {', '.join(MODES)}, not {backend!r}")


def _order(mode: str) -> Tuple[List[str], bool]:
    """Backends to try for a mode, and whether falling back between them is allowed."""
    if mode == "auto":
        return list(BACKENDS), True
    if mode == "qemu":
        return ["qemu-kvm", "qemu-tcg"], True
    if mode in BACKENDS:
        return [mode], False
    raise ValueError(f"mode must be one of {', '.join(MODES)}, not {mode!r}")


def run(cmd: Union[str, Sequence[str]], *, ifaces: Sequence[str] = ("vcan0",), mode: str = "auto",
        timeout: float = DEFAULT_TIMEOUT_S, env: Optional[Dict[str, str]] = None,
        cwd: Optional[str] = None, mem: str = DEFAULT_MEM, keep: bool = False) -> Result:
    """Runs cmd (a shell string or an argv list) with the vcan interfaces up.

    mode: a backend ("host", "uml", "qemu-kvm", "qemu-tcg"), "qemu" (KVM where usable, else
    TCG) or "auto" (the first that works, in that order; $ATTEKF_VCAN_MODE overrides auto).
    Raises VcanError if the command could not be run (the message names each backend's
    reason); the command's own failure is Result.returncode."""
    env = dict(os.environ if env is None else env)
    cwd = os.path.abspath(cwd or os.getcwd())
    if mode == "auto":
        mode = os.environ.get("ATTEKF_VCAN_MODE", "").strip() or "auto"
    order, fallback = _order(mode)
    shell = vcan_guest.as_shell(cmd)
    reasons: List[str] = []
    notes: List[str] = []
    for i, backend in enumerate(order):
        if fallback and backend in _failed:
            reasons.append(f"{backend}: {_failed[backend]}")
            continue
        if backend == "qemu-kvm" and fallback:
            why = vcan_qemu.available() or vcan_qemu.kvm_usable()
            if why:        # not an attempt: say why once, then TCG
                _failed[backend] = f"not usable: {why}"
                reasons.append(f"{backend}: not usable: {why}")
                _log(f"{backend}: not usable: {why}; trying {order[i + 1]}")
                continue
        try:
            res = _run_backend(backend, shell, ifaces, timeout, env, cwd, mem, keep)
        except BackendError as e:
            if not fallback or not e.boot_failed:
                raise VcanError(f"{backend}: {e.reason}" if fallback else str(e)) from e
            _failed[backend] = e.reason
            reasons.append(f"{backend}: {e.reason}")
            nxt = f"; trying {order[i + 1]}" if i + 1 < len(order) else ""
            _log(f"{backend}: {e.reason}{nxt}")
            notes.append(f"{backend}: {e.reason}")
            continue
        res.notes = notes + res.notes
        return res
    raise VcanError("no backend could run the command: " + " | ".join(reasons))


def _print_backends() -> int:
    for name, (why, expected) in backend_status().items():
        state = "usable" if why is None else f"not usable: {why}"
        print(f"{name:9s} {state}" + ("" if why is None or not expected else " (the set-up should provide it)"))
    if vcan_uml.available() is None:
        need, why = vcan_uml.wrapper_needed()
        print(f"{'':9s} UML XSTATE wrapper {'needed' if need else 'not needed'}: {why}")
    return 0


def main(argv: Optional[List[str]] = None) -> int:
    ap = argparse.ArgumentParser(
        prog="vcan_run.py",
        description="Run a command with virtual CAN interfaces up: directly if this kernel has CAN, "
                    "else inside user-mode Linux, else inside QEMU. Exits with the command's status "
                    "(125: no backend could run it).")
    ap.add_argument("--mode", choices=MODES, default="auto",
                    help="backend (default auto: the first that works; $ATTEKF_VCAN_MODE overrides auto)")
    ap.add_argument("--iface", action="append", default=None, metavar="NAME",
                    help="vcan interface to create (repeatable; default vcan0)")
    ap.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT_S, help="seconds (default 300)")
    ap.add_argument("--mem", default=DEFAULT_MEM, help="UML guest memory (default 512M)")
    ap.add_argument("--keep", action="store_true", help="keep the guest's work directory (debugging)")
    ap.add_argument("--shell", metavar="CMD", help="a shell command line instead of CMD ARGS")
    ap.add_argument("--repeat", type=int, default=1, metavar="N",
                    help="run N times and print each run's backend, boot and total time (benchmark)")
    ap.add_argument("--backends", action="store_true", help="print what each backend needs and exit")
    ap.add_argument("--prepare", action="store_true",
                    help="fetch Debian's kernel for the QEMU backend into the cache and exit")
    ap.add_argument("cmd", nargs=argparse.REMAINDER, help="-- CMD ARGS...")
    args = ap.parse_args(argv)
    if args.backends:
        return _print_backends()
    if args.prepare:
        try:
            k = vcan_qemu.prepare_kernel(log=lambda m: print(f"vcan_run: {m}"))
        except (RuntimeError, OSError, ValueError) as e:
            print(f"vcan_run: --prepare: {e}", file=sys.stderr)
            return 1
        print(f"vcan_run: QEMU guest kernel {k['package']} in {k['dir']}")
        return 0
    cmd: Union[str, List[str]]
    if args.shell is not None:
        cmd = args.shell
    else:
        cmd = args.cmd[1:] if args.cmd[:1] == ["--"] else args.cmd
        if not cmd:
            ap.error("no command given (use -- CMD ARGS... or --shell 'CMD')")
    if args.repeat < 1:
        ap.error("--repeat must be at least 1")
    try:
        vcan_uml.xstate_setting()
    except ValueError as e:
        ap.error(str(e))
    rc = 0
    for k in range(args.repeat):
        try:
            res = run(cmd, ifaces=args.iface or ["vcan0"], mode=args.mode, timeout=args.timeout,
                      mem=args.mem, keep=args.keep)
        except VcanError as e:
            print(f"vcan_run: {e}", file=sys.stderr)
            if args.repeat == 1:
                return EXIT_INFRA
            print(f"run {k + 1}: failed: {e}")
            rc = EXIT_INFRA
            continue
        if args.repeat == 1:
            sys.stdout.write(res.stdout)
            sys.stderr.write(res.stderr)
            return res.returncode
        print(f"run {k + 1}: {res.mode} exit {res.returncode}, command started after {res.boot_seconds:.2f} s, "
              f"total {res.seconds:.2f} s", flush=True)
        rc = rc or res.returncode
    return rc


if __name__ == "__main__":
    sys.exit(main())
