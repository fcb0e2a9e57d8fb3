"""Sub-commands of ``attekf``: one module each (NAME, HELP, add_arguments, run).

Shared here: :func:`run_command`, the one mapping from errors to a one-line message and an
exit status (attekf.errors), and the argument types and NAME=VALUE parsing the commands use
alike."""

from __future__ import annotations

import math
import os
import signal
import sys
import threading
from typing import Callable, Dict, Iterable, Tuple

from ..errors import AttekfError, Interrupted, UsageError


def _say(command: str, text: str) -> None:
    try:
        print(f"attekf {command}: {text}", file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass   # stderr gone: the exit status still tells


def run_command(command: str, body: Callable[[], int]) -> int:
    """Runs body() and turns every error into one line on stderr and an exit status:
    UsageError and the C library's SettingsError 2; InputError, OutputError, DeviceError,
    the C library's NativeError, a missing CAN database 1; Ctrl-C / SIGTERM 130. Anything
    else is a defect of the tools: one line naming the exception, exit 1 (the traceback with
    ATTEKF_TRACEBACK=1)."""
    from ..canproto import ProtocolError
    from ..native import NativeError, SettingsError

    try:
        return int(body() or 0)
    except Interrupted as exc:
        _say(command, f"interrupted: {exc}")
        return exc.exit_code
    except KeyboardInterrupt:
        _say(command, "interrupted: nothing written (outputs are only put in place when complete)")
        return Interrupted.exit_code
    except AttekfError as exc:
        _say(command, f"error: {exc}")
        return exc.exit_code
    except SettingsError as exc:
        _say(command, f"error: {' '.join(str(exc).split())}")
        return 2
    except (NativeError, ProtocolError) as exc:
        _say(command, f"error: {' '.join(str(exc).split())}")
        return 1
    except ModuleNotFoundError as exc:   # an optional package a part of the tools needs
        from ..extras import PACKAGES, message
        root = (exc.name or "").split(".")[0]
        if root not in PACKAGES:
            raise
        _say(command, f"error: {message(root, f'attekf {command}')}")
        return 2
    except BrokenPipeError:
        # the reader of stdout went away (attekf eval ... | head): no traceback at exit
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return 1
    except MemoryError:
        _say(command, "error: out of memory")
        return 1
    except OSError as exc:   # the machine refused (disk full, I/O error): not a defect
        where = f"{exc.filename}: " if exc.filename else ""
        _say(command, f"error: {where}{exc.strerror or ' '.join(str(exc).split())}")
        return 1
    except Exception as exc:  # a defect: still one line, but say that it is one
        if os.environ.get("ATTEKF_TRACEBACK"):
            raise
        text = " ".join(str(exc).split()) or "(no message)"
        _say(command, f"error: internal error {type(exc).__name__}: {text} "
                      "(a defect of attekf; ATTEKF_TRACEBACK=1 shows where)")
        return 1


def run_guarded(fail, body):
    """Runs body(), mapping the errors every command reports alike to fail(msg, code) (kept
    for callers of the earlier interface; commands now go through run_command)."""
    from ..native import NativeError, SettingsError

    try:
        return body()
    except AttekfError as exc:
        return fail(str(exc), exc.exit_code)
    except SettingsError as exc:
        return fail(str(exc), 2)
    except NativeError as exc:
        return fail(" ".join(str(exc).split()))


def set_signal(sig, handler):
    """signal.signal in the main thread (where Python delivers signals); elsewhere (a command
    run from a thread, as the tests do) nothing, returning None."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(sig, handler)


# ---------------------------------------------------------------------------------------------
# Argument types (argparse reports their ValueError as "invalid <name> value")
# ---------------------------------------------------------------------------------------------
def _checked(convert, ok, name: str):
    """An argparse type: convert(text), refused (ValueError) unless ok(value). argparse
    names `name` in its message: "invalid number > 0 value: '0'"."""
    def parse(text: str):
        v = convert(text)
        if not ok(v):
            raise ValueError(text)
        return v
    parse.__name__ = name
    return parse


finite_float = _checked(float, math.isfinite, "number")
nonneg_float = _checked(float, lambda v: math.isfinite(v) and v >= 0, "number >= 0")
positive_float = _checked(float, lambda v: math.isfinite(v) and v > 0, "number > 0")
nonneg_int = _checked(int, lambda v: v >= 0, "integer >= 0")
positive_int = _checked(int, lambda v: v >= 1, "integer >= 1")
fraction = _checked(float, lambda v: 0.0 <= v < 1.0, "fraction in [0, 1)")


def parse_pair(item: str, what: str) -> Tuple[str, float]:
    """NAME=VALUE of a command-line option -> (name, finite float); UsageError otherwise."""
    name, sep, value = item.partition("=")
    if not sep or not name.strip():
        raise UsageError(f"{what} {item!r}: expected NAME=VALUE")
    try:
        v = float(value)
    except ValueError:
        raise UsageError(f"{what} {item!r}: '{value.strip()}' is not a number") from None
    if not math.isfinite(v):
        raise UsageError(f"{what} {item!r}: '{value.strip()}' is not a finite number")
    return name.strip(), v


def parse_pairs(items: Iterable[str], what: str) -> Dict[str, float]:
    return dict(parse_pair(i, what) for i in items)


def check_settings(scalar: str, settings: Dict[str, float], source: str = "") -> None:
    """Lets the C library check estimator settings now (before any work); a refusal is a
    SettingsError (exit 2), prefixed with the file the settings came from."""
    from .. import native

    try:
        native._make_settings(native.load(scalar), settings)
    except native.SettingsError as exc:
        if source:
            raise native.SettingsError(f"{source}: {exc}") from None
        raise



# ---------------------------------------------------------------------------------------------
# Estimator settings options (eval, run)
# ---------------------------------------------------------------------------------------------
SCALAR_HELP = ("which C build runs: float (what runs on the microcontroller, default), double, or "
               "fixed (Q-format fixed point)")


def add_settings_arguments(p) -> None:
    """--scalar, --set NAME=VALUE, --settings FILE, --list-settings."""
    p.add_argument("--scalar", choices=("float", "double", "fixed"), default="float", help=SCALAR_HELP)
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="change an estimator setting (repeatable; see --list-settings)")
    p.add_argument("--settings", metavar="FILE",
                   help="estimator settings from a TOML (.toml) or JSON file of {name: value}")
    p.add_argument("--list-settings", action="store_true",
                   help="print the estimator's settings (unit, range, default, meaning) and exit")


def parse_settings(args) -> Dict[str, float]:
    """--settings FILE then --set NAME=VALUE (later wins); each checked by the C library now,
    so a refused setting fails before any work (exit 2, naming its origin)."""
    from ..io import read_settings_json
    settings: Dict[str, float] = {}
    if args.settings:
        from_file = read_settings_json(args.settings)
        if not args.list_settings:
            check_settings(args.scalar, from_file, args.settings)
        settings.update(from_file)
    for item in args.set:
        name, value = parse_pair(item, "--set")
        settings[name] = value
    if settings and not args.list_settings:
        check_settings(args.scalar, settings)
    return settings


def list_settings(scalar: str) -> int:
    """Prints every setting of the C library: name, default, unit, range, meaning."""
    from ..native import setting_info
    info = setting_info(scalar)
    w = max(len(n) for n in info)
    print(f"estimator settings ({scalar} build): name, default, unit, accepted range, meaning")
    for name, row in info.items():
        lo, hi = row["range"]
        print(f"  {name.ljust(w)}  {row['default']!s:>14}  {row['unit']:<16} [{lo:g}, {hi:g}]  {row['help']}")
    return 0
