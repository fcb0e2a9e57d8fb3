"""Outputs that are either complete or absent.

A command declares every file it will write before the work starts (:meth:`Outputs.file`,
:meth:`Outputs.directory`): each is checked then, so that an unwritable or impossible path
fails in a second with one line instead of after the whole run. Files are written under a
temporary name next to their final one (``.partial-<pid>-<name>``, same directory, so the
rename is atomic and the extension, which selects the format, is kept) and renamed into place
together by :meth:`Outputs.commit` once the command has finished. An error or an interruption
before that removes the temporary files (:meth:`Outputs.abort`), and files already at the
final names stay as they were: nothing half-written ever looks complete. A process killed
with SIGKILL leaves only ``.partial-*`` names behind.

    with Outputs() as out:
        table = out.file(args.table, "--table")         # checked now
        ...                                              # the work
        with out.open(table) as fh:                      # writes the temporary file
            fh.write(text)
        out.commit()                                     # all renamed into place
"""

from __future__ import annotations

import os
import signal
import threading
from contextlib import contextmanager
from typing import Dict, Iterable, List, Optional

from .errors import Interrupted, OutputError, UsageError

PARTIAL_PREFIX = ".partial-"


def _nearest_existing(path: str) -> str:
    d = path
    while d and not os.path.lexists(d):
        parent = os.path.dirname(d)
        if parent == d:
            break
        d = parent
    return d or "."


def _probe_directory(d: str, path: str, what: str) -> None:
    """Creates and removes a file in d: the only test that also holds for root, read-only
    mounts and full quota."""
    probe = os.path.join(d, f"{PARTIAL_PREFIX}{os.getpid()}-probe")
    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        return
    except OSError as exc:
        raise OutputError(f"{path}: cannot write ({what}): {d}: {exc.strerror or exc}") from None
    os.close(fd)
    os.unlink(probe)


def check_file(path: str, what: str) -> str:
    """Raises OutputError unless a file can be created (or replaced) at path. Directories on
    the way may be missing (they are created when the file is written). Returns the path."""
    if not path or path.endswith(os.sep):
        raise UsageError(f"{what}: {path!r} is not a file name")
    if os.path.isdir(path):
        raise OutputError(f"{path}: is a directory ({what} needs a file name)")
    if os.path.lexists(path) and not os.path.isfile(path):
        raise OutputError(f"{path}: exists and is not a regular file ({what})")
    base = _nearest_existing(os.path.dirname(os.path.abspath(path)))
    if not os.path.isdir(base):
        raise OutputError(f"{path}: cannot write ({what}): {base} is not a directory")
    if os.path.exists(path) and not os.access(path, os.W_OK):
        raise OutputError(f"{path}: cannot write ({what}): the file is read-only")
    _probe_directory(base, path, what)
    return path


def check_directory(path: str, what: str) -> str:
    """Raises OutputError unless path is (or can be created as) a writable directory."""
    if not path:
        raise UsageError(f"{what}: empty directory name")
    if os.path.lexists(path) and not os.path.isdir(path):
        raise OutputError(f"{path}: exists and is not a directory ({what} needs a directory)")
    base = _nearest_existing(os.path.abspath(path))
    if not os.path.isdir(base):
        raise OutputError(f"{path}: cannot create ({what}): {base} is not a directory")
    _probe_directory(base, path, what)
    return path


@contextmanager
def _signals_deferred():
    """SIGINT and SIGTERM wait while the renames run (a rename set cut in the middle would
    mix this run's files with an earlier run's)."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    sigs = {signal.SIGINT, signal.SIGTERM}
    old = signal.pthread_sigmask(signal.SIG_BLOCK, sigs)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


class Outputs:
    """The outputs of one command run (see the module docstring). Usable as a context
    manager: leaving it without commit() (an exception, Ctrl-C) aborts."""

    def __init__(self) -> None:
        self._final: Dict[str, str] = {}      # real path -> path as the user gave it
        self._what: Dict[str, str] = {}
        self._temp: Dict[str, str] = {}       # real path -> temporary path (once written)
        self._made_dirs: List[str] = []
        self._inputs: Dict[str, str] = {}
        self.committed: List[str] = []

    # -- declaring --------------------------------------------------------------------------
    def _key(self, path: str) -> str:
        return os.path.realpath(path)

    def _declare(self, path: str, what: str) -> None:
        key = self._key(path)
        if key in self._final:
            raise UsageError(f"{path}: named twice as an output ({self._what[key]} and {what})")
        if key in self._inputs:
            raise UsageError(f"{path}: {what} would overwrite the input {self._inputs[key]}")
        self._final[key] = path
        self._what[key] = what

    def inputs(self, paths: Iterable[Optional[str]]) -> None:
        """Input files that no output may replace."""
        for p in paths:
            if p:
                key = self._key(p)
                if key in self._final:
                    raise UsageError(f"{p}: {self._what[key]} would overwrite this input")
                self._inputs[key] = p

    def file(self, path: Optional[str], what: str) -> Optional[str]:
        """Declares and checks an output file (None passes through)."""
        if path is None:
            return None
        check_file(path, what)
        self._declare(path, what)
        return path

    def directory(self, path: Optional[str], what: str) -> Optional[str]:
        """Checks an output directory; its files are declared with file()."""
        if path is None:
            return None
        check_directory(path, what)
        return path

    # -- writing ----------------------------------------------------------------------------
    def temp(self, path: str) -> str:
        """The temporary path to write `path` to (its directory is created)."""
        key = self._key(path)
        if key not in self._final:
            raise KeyError(f"{path} was not declared as an output")
        if key not in self._temp:
            d = os.path.dirname(os.path.abspath(path))
            self._makedirs(d)
            self._temp[key] = os.path.join(d, f"{PARTIAL_PREFIX}{os.getpid()}-{os.path.basename(path)}")
        return self._temp[key]

    def open(self, path: str, mode: str = "w", **kwargs):
        """open() of the temporary file of `path` (text files default to UTF-8)."""
        if "b" not in mode:
            kwargs.setdefault("encoding", "utf-8")
        tmp = self.temp(path)
        try:
            return open(tmp, mode, **kwargs)
        except OSError as exc:
            raise OutputError(f"{path}: cannot write: {exc.strerror or exc}") from None

    def _makedirs(self, d: str) -> None:
        missing = []
        while d and not os.path.isdir(d):
            missing.append(d)
            parent = os.path.dirname(d)
            if parent == d:
                break
            d = parent
        for m in reversed(missing):
            try:
                os.mkdir(m)
            except FileExistsError:
                continue
            except OSError as exc:
                raise OutputError(f"{m}: cannot create directory: {exc.strerror or exc}") from None
            self._made_dirs.append(m)

    @property
    def pending(self) -> List[str]:
        """Declared outputs written so far (to their temporary names), as given."""
        return [self._final[k] for k in self._temp]

    # -- finishing --------------------------------------------------------------------------
    def commit(self) -> List[str]:
        """Renames every written temporary file into place; returns the final paths."""
        done: List[str] = []
        try:
            with _signals_deferred():
                for key, tmp in list(self._temp.items()):
                    final = self._final[key]
                    try:
                        os.replace(tmp, final)
                    except OSError as exc:
                        raise OutputError(f"{final}: cannot write: {exc.strerror or exc}") from None
                    del self._temp[key]
                    done.append(final)
        except KeyboardInterrupt:
            # a signal that came during the renames is delivered once they are done
            self.committed, self._made_dirs = done, []
            raise Interrupted(f"after the outputs were complete and in place ({len(done)} file(s))") from None
        self.committed = done
        self._made_dirs = []
        return done

    def abort(self) -> None:
        """Removes the temporary files and the directories created for them."""
        for tmp in self._temp.values():
            try:
                os.unlink(tmp)
            except OSError:
                pass
        self._temp.clear()
        for d in reversed(self._made_dirs):
            try:
                os.rmdir(d)
            except OSError:
                pass
        self._made_dirs = []

    def __enter__(self) -> "Outputs":
        return self

    def __exit__(self, *exc) -> None:
        self.abort()   # after commit() there is nothing left to remove


def makedirs_for(path: str) -> None:
    """Creates the directory of path; OutputError naming it otherwise."""
    d = os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(d, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{path}: cannot create its directory: {exc.strerror or exc}") from None


@contextmanager
def atomic_path(path: str):
    """A temporary path next to `path` to write to; renamed to `path` when the block ends
    normally, removed when it raises (OSError becomes OutputError naming `path`). For the
    writers of single files; a command's set of outputs is an Outputs."""
    makedirs_for(path)
    tmp = os.path.join(os.path.dirname(os.path.abspath(path)),
                       f"{PARTIAL_PREFIX}{os.getpid()}-{os.path.basename(path)}")
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError) and not isinstance(exc, (OutputError,)):
            raise OutputError(f"{path}: cannot write: {exc.strerror or exc}") from None
        raise
