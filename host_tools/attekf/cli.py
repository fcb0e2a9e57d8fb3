"""The ``attekf`` command: one entry point, one sub-command per module in
``attekf/commands`` (each module defines NAME, HELP, add_arguments(parser) and run(args)).

Every command runs through :func:`attekf.commands.run_command`, the one place where errors
become a one-line message and an exit status (attekf.errors)."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import signal
import sys
import threading
from typing import List, NoReturn, Optional

from . import __version__, commands

# What each command needs beyond numpy, and the extra of the package that installs it
# (pyproject.toml); checked before the command runs (attekf.extras).
NEEDS = {
    "sim": (("tqdm",), "tools"),
    "eval": (("tqdm",), "tools"),
    "run": (("tqdm",), "tools"),
    "replay": (("tqdm", "can", "cantools"), "can"),
    "record": (("tqdm", "can", "cantools"), "can"),
    "bench": (("tqdm", "h5py"), "bench"),
    "cv": (("tqdm", "h5py"), "bench"),
}


class UsageExit(SystemExit):
    """argparse's usage error (already printed): main() returns 2 for it."""


class Parser(argparse.ArgumentParser):
    """argparse with its usage errors on one line (``attekf eval: error: ...``), exit 2."""

    def error(self, message: str) -> NoReturn:
        msg = " ".join(message.split())
        sys.stderr.write(f"{self.prog}: error: {msg} (see {self.prog} --help)\n")
        raise UsageExit(2)


def _command_modules():
    mods = []
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        mods.append(importlib.import_module(f"{commands.__name__}.{info.name}"))
    return mods


def build_parser() -> argparse.ArgumentParser:
    ap = Parser(
        prog="attekf",
        description="Host tools for the attitude EKF: simulate recordings, run the C estimator "
        "over them, replay them onto a CAN bus, record the estimator's output, evaluate "
        "against ground truth and benchmark. Each command has its own --help. The Python API: "
        "python -c 'import attekf; help(attekf)'.",
        epilog="Extras: sim, eval, run need pip install 'attekf[tools]'; replay, record "
               "'attekf[can]'; bench, cv 'attekf[bench]'. Exit status: 0 done, 1 a file or device "
               "could not be used, 2 usage error (also: a missing extra), 130 interrupted.",
    )
    ap.add_argument("--version", action="version", version=f"attekf {__version__}")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    sub.required = True
    ap.commands = {}
    for mod in _command_modules():
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=getattr(mod, "DESCRIPTION", mod.HELP),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        p.add_argument("-q", "--quiet", action="store_true", help="no progress bars or chatter")
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
        ap.commands[mod.NAME] = p
    return ap


def _terminate(_sig, _frame):
    raise KeyboardInterrupt


def _run(args) -> int:
    from .extras import message, missing
    modules, extra = NEEDS.get(args.command, ((), ""))
    absent = missing(modules)
    if absent:
        from .errors import MissingExtra
        raise MissingExtra(message(absent[0], f"attekf {args.command}", extra))
    return args._run(args)


def main(argv: Optional[List[str]] = None) -> int:
    """Runs one command; returns its exit status (--help and --version exit 0 through
    SystemExit, as argparse does)."""
    ap = build_parser()
    try:
        args, extra = ap.parse_known_args(argv)
        if extra:   # reported by the command's parser, so the line names the command
            ap.commands[args.command].error(f"unrecognized arguments: {' '.join(extra)}")
    except UsageExit as exc:
        return int(exc.code)
    old = None
    if threading.current_thread() is threading.main_thread():
        # SIGTERM cleans up like Ctrl-C (temporary outputs removed); record and replay
        # install their own handler while they listen or send
        old = signal.signal(signal.SIGTERM, _terminate)
    try:
        return commands.run_command(args.command, lambda: _run(args))
    finally:
        if old is not None:
            signal.signal(signal.SIGTERM, old)


if __name__ == "__main__":
    sys.exit(main())
