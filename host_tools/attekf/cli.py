"""The ``attekf`` command: one entry point, one sub-command per module in
``attekf/commands`` (each module defines NAME, HELP, add_arguments(parser) and run(args))."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from typing import List, Optional

from . import __version__, commands


def _command_modules():
    mods = []
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        mods.append(importlib.import_module(f"{commands.__name__}.{info.name}"))
    return mods


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="attekf",
        description="Host tools for the attitude EKF: simulate recordings, run the C estimator "
        "over them, replay them onto a CAN bus, record the estimator's output, evaluate "
        "against ground truth and benchmark.",
    )
    ap.add_argument("--version", action="version", version=f"attekf {__version__}")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for mod in _command_modules():
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=getattr(mod, "DESCRIPTION", mod.HELP),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        p.add_argument("-q", "--quiet", action="store_true", help="no progress bars or chatter")
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return ap


def main(argv: Optional[List[str]] = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except KeyboardInterrupt:
        print("attekf: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
