#!/usr/bin/env python3
"""Run a command on a machine with a virtual CAN interface (vcan0) up, and return its output
and exit status, whatever CAN support this machine's kernel and CPU have (docs/hil.md).

Backends, tried in this order by mode auto:

  host      this kernel's CAN (``socket(PF_CAN)`` works): the command runs directly, after
            the interfaces are created if missing (root)
  uml       user-mode Linux (vcan_uml.py): Debian's ``linux.uml`` with the host's ``/`` as its
            root; with the ptrace XSTATE wrapper of uml_xstate/ where the host kernel refuses
            UML's XSTATE writes (asked by a probe), and one retry with it after a boot that
            failed with ``ptrace set fp regs failed``
  qemu-kvm  QEMU with KVM (vcan_qemu.py): Debian's kernel, the host's ``/`` over virtio-9p;
            only where the CPU has vmx/svm, and given up when the guest prints nothing
            within a few seconds or QEMU fails
  qemu-tcg  the same under emulation

Each backend that cannot run the command logs one line with the root cause on stderr, and the
next one is tried; a backend that failed is not tried again in the same process. The
decisions are in vcan_choice.py (pure logic, tested with fakes). The command runs in the
current directory with the current environment; its stdout, stderr and exit status come back
through files (no TTY needed; CI has no stdin).

Command line::

    tests/vm/vcan_run.py [--mode auto|host|uml|qemu|qemu-kvm|qemu-tcg] [--timeout S]
                         [--iface vcan0 ...] -- CMD ARGS...
    tests/vm/vcan_run.py --shell 'candump -n 1 vcan0 & cansend vcan0 123#00; wait'
    tests/vm/vcan_run.py --backends        what each backend needs and whether it has it
    tests/vm/vcan_run.py --prepare         fetch the QEMU guest kernel into the cache

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
import vcan_choice as choice  # noqa: E402
import vcan_guest  # noqa: E402
import vcan_qemu  # noqa: E402
import vcan_uml  # noqa: E402
from vcan_choice import BACKENDS, EXIT_INFRA, MODES, BackendError, Result, VcanError  # noqa: E402,F401

DEFAULT_TIMEOUT_S = 300.0
DEFAULT_MEM = "512M"
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


def host_precheck(ifaces: Sequence[str]) -> Optional[str]:
    """Why the host's own CAN cannot be used, or None."""
    why = host_can_reason()
    if why is None and os.geteuid() != 0:
        missing = [n for n in ifaces if not os.path.exists(f"/sys/class/net/{n}")]
        if missing:
            why = f"{', '.join(missing)} missing and not root (cannot create it)"
    return why


def precheck(backend: str, ifaces: Sequence[str] = ("vcan0",), kvm_flags: bool = True) -> Optional[str]:
    """Why a backend cannot be used here, found without booting anything, or None.
    kvm_flags=False: KVM is worth a try on a CPU without vmx/svm too."""
    if backend == "host":
        return host_precheck(ifaces)
    if backend == "uml":
        return vcan_uml.available()
    if backend == "qemu-kvm":
        return vcan_qemu.available() or vcan_qemu.kvm_usable(kvm_flags)
    if backend == "qemu-tcg":
        return vcan_qemu.available()
    raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, not {backend!r}")


def backend_status(ifaces: Sequence[str] = ("vcan0",)) -> Dict[str, Tuple[Optional[str], bool]]:
    """For each backend: (why it cannot be used here, or None; whether scripts/setup.sh
    installs it, so that its absence is a broken set-up). Host CAN and KVM depend on the
    machine; UML and QEMU/TCG are installed by the set-up. No guest is booted."""
    return {b: (precheck(b, ifaces), b in ("uml", "qemu-tcg")) for b in BACKENDS}


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
    return vcan_qemu.run(cmd, ifaces, timeout, env, cwd, keep, backend.split("-")[1])


def run(cmd: Union[str, Sequence[str]], *, ifaces: Sequence[str] = ("vcan0",), mode: str = "auto",
        timeout: float = DEFAULT_TIMEOUT_S, env: Optional[Dict[str, str]] = None,
        cwd: Optional[str] = None, mem: str = DEFAULT_MEM, keep: bool = False,
        kvm_flags: bool = True) -> Result:
    """Runs cmd (a shell string or an argv list) with the vcan interfaces up.

    mode: a backend ("host", "uml", "qemu-kvm", "qemu-tcg"), "qemu" (KVM where usable, else
    TCG) or "auto" (the first that works, in that order; $ATTEKF_VCAN_MODE overrides auto).
    kvm_flags=False tries KVM on a CPU without vmx/svm too (the tests: what does it do there).
    Raises VcanError if the command could not be run (the message names each backend's
    reason); the command's own failure is Result.returncode."""
    env = dict(os.environ if env is None else env)
    cwd = os.path.abspath(cwd or os.getcwd())
    if mode == "auto":
        mode = os.environ.get("ATTEKF_VCAN_MODE", "").strip() or "auto"
    backends, fallback = choice.order(mode)
    vcan_uml.xstate_setting()            # a wrong $ATTEKF_UML_XSTATE is an error whatever runs
    shell = vcan_guest.as_shell(cmd)
    return choice.first_working(
        backends, fallback,
        precheck=lambda b: precheck(b, ifaces, kvm_flags),
        attempt=lambda b: _run_backend(b, shell, ifaces, timeout, env, cwd, mem, keep),
        failed=_failed, log=_log)


def _print_backends() -> int:
    for name, (why, expected) in backend_status().items():
        state = "usable" if why is None else f"not usable: {why}"
        print(f"{name:9s} {state}" + ("" if why is None or not expected else " (the set-up should provide it)"))
    if vcan_uml.available() is None:
        print(f"{'':9s} UML: {vcan_uml.wrapper_plan().why}")
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
    try:
        vcan_uml.xstate_setting()
        if args.mode == "auto":
            choice.order(os.environ.get("ATTEKF_VCAN_MODE", "").strip() or "auto")
    except ValueError as e:
        ap.error(f"{e} ($ATTEKF_VCAN_MODE, $ATTEKF_UML_XSTATE)")
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
