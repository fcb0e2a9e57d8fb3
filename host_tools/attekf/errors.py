"""The errors the host tools report to a user, and the exit status of each.

Every failure a user can cause ends as one line on stderr, ``attekf <command>: error: ...``,
and one exit status (docs/host_tools.md, "Exit status"):

====  =====================================================================================
0     done
1     a file or device could not be used: an input that cannot be read or is malformed
      (:class:`InputError`), an output that cannot be written (:class:`OutputError`), a CAN
      interface that cannot be opened or fails (:class:`DeviceError`), the C library failing
2     the command line itself is wrong (:class:`UsageError`): missing or conflicting options,
      a value that is not a number or out of range, an unknown setting, method or interface,
      an estimator setting the filter refuses
130   interrupted (Ctrl-C, SIGTERM): outputs are never left half-written (attekf.outputs)
====  =====================================================================================

An :class:`InputError` carries where the problem is (``path``, ``line``, ``field``) besides
its one-line message, so that callers and tests can check the location without parsing text.
"""

from __future__ import annotations

from typing import Optional


class AttekfError(Exception):
    """Base of the errors reported as one line; ``exit_code`` is the process exit status."""

    exit_code = 1

    def __str__(self) -> str:
        # never more than one line, whatever the underlying library put in the text
        return " ".join(super().__str__().split())


class InputError(AttekfError):
    """A file that cannot be used as given. str(err) is one line naming the file and where.

    InputError("path: line 3: column t_s: ...") (the message already names the place), or
    InputError("empty cell", path="a.csv", line=3, field="t_s") which composes the same
    message. ``path``, ``line`` (1-based) and ``field`` (a column, dataset or option name)
    are kept as attributes (None where unknown)."""

    def __init__(self, message: str, path: Optional[str] = None, line: Optional[int] = None,
                 field: Optional[str] = None):
        self.path, self.line, self.field = path, line, field
        if path is not None:
            where = [str(path)]
            if line is not None:
                where.append(f"line {line}")
            if field is not None:
                where.append(field if " " in field else f"column {field}")
            message = ": ".join(where + [message])
        super().__init__(message)


class OutputError(AttekfError):
    """An output that cannot be written (missing permission, a file where a directory is
    needed, a full disk...). The message names the path and the option it came from."""


class DeviceError(AttekfError):
    """A CAN interface that cannot be opened or fails while in use."""


class UsageError(AttekfError):
    """The command line is wrong: exit status 2."""

    exit_code = 2


class Interrupted(AttekfError):
    """Ctrl-C / SIGTERM, with what was left behind in the message: exit status 130."""

    exit_code = 130


class MissingExtra(UsageError):
    """A command or file format needs a Python package that is not installed; the message
    names the extra of the attekf package that brings it (attekf.extras). Exit status 2."""
