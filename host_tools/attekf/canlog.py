"""Reading CAN log files (candump ``.log``, Vector ``.asc`` and ``.blf``) for `attekf replay`
and `attekf record --from-log`: one reader, so that both accept and refuse the same files.

:func:`read_frames` yields the classic data frames ``(t_s, id, data, extended)``; error,
remote and CAN FD frames are skipped (and counted in :class:`LogStats`). Every problem is an
InputError naming the file and the line (text logs) or the byte offset (BLF):

* candump: the line format of ``candump -L`` and python-can's writer, as strict as
  attekf-node's reader (firmware/app/candump.c): ``(SECONDS.FRACTION) CHANNEL ID#DATA``, 1-3
  hex digits for an 11-bit id (<= 7FF), 4-8 for a 29-bit one, 0-8 data bytes; blank lines and
  lines starting with '#' are skipped. A last line without its line end is a truncated file.
* ASC: python-can's reader; a file without its closing ``End TriggerBlock`` is truncated.
* BLF: python-can's object parser, with the checks it leaves out: the file size against the
  header's, every object and compressed container complete.

A log without any data frame is an error too (replay and record agree on it).
"""

from __future__ import annotations

import os
import re
import struct
import zlib
from dataclasses import dataclass
from typing import Iterator, List, Optional, Sequence, Tuple

from .csvtext import read_text_lines
from .errors import InputError, UsageError

LOG_EXTS = (".log", ".asc", ".blf")
Frame = Tuple[float, int, bytes, bool]

_CANDUMP = re.compile(r"\((?P<t>[^)]*)\)\s+(?P<ch>\S+)\s+(?P<id>[^#\s]*)#(?P<data>\S*)(?:\s+(?P<rest>.*))?$")
_TIME = re.compile(r"\d+\.\d+$")
_HEX = re.compile(r"[0-9A-Fa-f]+$")
CAN_ERR_FLAG = 0x20000000


@dataclass
class LogStats:
    """What a read skipped: error, remote and CAN FD frames."""
    frames: int = 0
    error_frames: int = 0
    remote_frames: int = 0
    fd_frames: int = 0


def writable_exts() -> Tuple[str, ...]:
    """Extensions python-can writes CAN logs in (a superset of LOG_EXTS)."""
    from can.io.logger import MESSAGE_WRITERS
    return tuple(sorted(MESSAGE_WRITERS))


def check_log_name(path: str, what: str, output: bool = False) -> str:
    """The extension of a CAN log's name, if it can be read (LOG_EXTS) or, for an output,
    written (writable_exts); else InputError (an input file) or UsageError (an output name:
    the command line is wrong)."""
    ext = os.path.splitext(path)[1].lower()
    known = writable_exts() if output else LOG_EXTS
    if ext not in known:
        err = UsageError if output else InputError
        raise err(f"{path}: {what}: unknown CAN log format '{ext or '(none)'}' "
                  f"(expected {', '.join(known)})")
    if output:
        problem = _writer_problem(ext)
        if problem:
            raise UsageError(f"{path}: {what}: python-can cannot write '{ext}' logs here: {problem}")
    return ext


def _writer_problem(ext: str) -> Optional[str]:
    """Why python-can's writer for `ext` cannot be used (some need an optional package, e.g.
    .mf4 asammdf), found by opening one on a scratch file before any work; None if it can."""
    import tempfile

    import can
    with tempfile.TemporaryDirectory(prefix="attekf-logprobe-") as d:
        try:
            can.Logger(os.path.join(d, "probe" + ext)).stop()
        except Exception as e:   # writers raise NotImplementedError, ImportError, ValueError, ...
            return " ".join(str(e).split()) or type(e).__name__
    return None


def read_frames(path: str, stop: Optional[List[bool]] = None,
                stats: Optional[LogStats] = None) -> Iterator[Frame]:
    """The data frames of a CAN log in file order (see the module docstring). stop: a
    one-element list; reading ends early once stop[0] is true (Ctrl-C)."""
    ext = check_log_name(path, "input")
    if not os.path.exists(path):
        raise InputError(f"{path}: no such file")
    if os.path.isdir(path):
        raise InputError(f"{path}: is a directory, expected a CAN log")
    st = stats if stats is not None else LogStats()
    reader = {".log": _candump, ".asc": _asc, ".blf": _blf}[ext]
    for frame in reader(path, st):
        st.frames += 1
        yield frame
        if stop is not None and stop[0]:
            return
    if st.frames == 0:
        skipped = [f"{n} {k}" for k, n in (("error", st.error_frames), ("remote", st.remote_frames),
                                           ("CAN FD", st.fd_frames)) if n]
        raise InputError(f"{path}: no CAN data frames in the log"
                         + (f" (only {', '.join(skipped)} frames)" if skipped else ""))


# ---------------------------------------------------------------------------------------------
# candump
# ---------------------------------------------------------------------------------------------
def _short(text: str, n: int = 40) -> str:
    text = text.strip()
    return repr(text if len(text) <= n else text[:n] + "...")


def parse_candump_line(line: str, where: str) -> Optional[Tuple[str, float, int, bytes, bool]]:
    """One candump line -> (kind, t, id, data, extended) with kind 'data', 'error',
    'remote' or 'fd'; None for a blank or comment line; InputError(where: ...) if bad."""
    s = line.strip()
    if not s or s.startswith("#"):
        return None
    m = _CANDUMP.match(s)
    if m is None:
        raise InputError(f"{where}: not a candump line: expected '(SECONDS) CHANNEL ID#DATA', "
                         f"got {_short(s)}")
    if not _TIME.match(m["t"]):
        raise InputError(f"{where}: time stamp {_short('(' + m['t'] + ')')} is not "
                         "(SECONDS.FRACTION)")
    t = float(m["t"])
    ident = m["id"]
    if not ident or not _HEX.match(ident) or len(ident) > 8:
        raise InputError(f"{where}: id {_short(ident)} is not 1 to 8 hexadecimal digits")
    fid = int(ident, 16)
    extended = len(ident) > 3
    if extended and fid & CAN_ERR_FLAG and fid < 2 * CAN_ERR_FLAG:
        return "error", t, fid & 0x1FFFFFFF, b"", True
    if fid > (0x1FFFFFFF if extended else 0x7FF):
        raise InputError(f"{where}: id {ident} beyond {'0x1FFFFFFF (29-bit)' if extended else '0x7FF (11-bit)'}")
    data = m["data"]
    if data[:1] in ("R", "r"):
        return "remote", t, fid, b"", extended
    if data.startswith("#"):
        return "fd", t, fid, b"", extended
    if data and (len(data) % 2 or not _HEX.match(data)):
        raise InputError(f"{where}: data {_short(data)} is not whole bytes of hexadecimal digits")
    if len(data) > 16:
        raise InputError(f"{where}: data has {len(data) // 2} bytes, a classic CAN frame at most 8")
    rest = m["rest"]
    if rest is not None and rest not in ("R", "T", "r", "t"):
        raise InputError(f"{where}: unexpected {_short(rest)} after the data")
    return "data", t, fid, bytes.fromhex(data), extended


def _count(st: LogStats, kind: str) -> None:
    if kind == "error":
        st.error_frames += 1
    elif kind == "remote":
        st.remote_frames += 1
    elif kind == "fd":
        st.fd_frames += 1


def _candump(path: str, st: LogStats) -> Iterator[Frame]:
    lines = read_text_lines(path)
    with open(path, "rb") as fh:
        fh.seek(0, os.SEEK_END)
        size = fh.tell()
        if size:
            fh.seek(size - 1)
            ends_with_newline = fh.read(1) in (b"\n", b"\r")
        else:
            ends_with_newline = True
    last = len(lines)
    while last > 0 and not lines[last - 1].strip():
        last -= 1
    for i, line in enumerate(lines[:last]):
        if i == last - 1 and not ends_with_newline and line.strip() and not line.lstrip().startswith("#"):
            raise InputError(f"{path}: line {i + 1}: the last line has no line end: the log is "
                             "truncated (candump ends every line with one)")
        r = parse_candump_line(line, f"{path}: line {i + 1}")
        if r is None:
            continue
        kind, t, fid, data, ext = r
        if kind != "data":
            _count(st, kind)
            continue
        yield t, fid, data, ext


def _data_frame(m, st: LogStats) -> Optional[Frame]:
    """A python-can Message as a Frame, or None (counted in st) for error, remote and CAN FD
    frames."""
    if m.is_error_frame:
        st.error_frames += 1
    elif m.is_remote_frame:
        st.remote_frames += 1
    elif m.is_fd or len(m.data) > 8:
        st.fd_frames += 1
    else:
        return float(m.timestamp), int(m.arbitration_id), bytes(m.data), bool(m.is_extended_id)
    return None


# ---------------------------------------------------------------------------------------------
# ASC
# ---------------------------------------------------------------------------------------------
class _Lines:
    """Lines for python-can's ASCReader, counting what it has read (for error messages)."""

    def __init__(self, lines: Sequence[str]):
        self._lines = lines
        self.n = 0

    def __iter__(self):
        return self

    def __next__(self) -> str:
        if self.n >= len(self._lines):
            raise StopIteration
        self.n += 1
        return self._lines[self.n - 1] + "\n"

    def read(self, *_args) -> str:
        return ""

    def close(self) -> None:
        pass


def _asc(path: str, st: LogStats) -> Iterator[Frame]:
    from can.io.asc import ASCReader
    lines = read_text_lines(path)
    body = [ln for ln in lines if ln.strip()]
    if not body or body[-1].strip().lower() != "end triggerblock":
        raise InputError(f"{path}: line {len(lines)}: no closing 'End TriggerBlock': the log is "
                         "truncated or not an ASC log")
    src = _Lines(lines)
    try:
        for m in ASCReader(src):
            frame = _data_frame(m, st)
            if frame is not None:
                yield frame
    except InputError:
        raise
    except Exception as exc:  # python-can's parser raises ValueError, IndexError, KeyError ...
        raise InputError(f"{path}: line {src.n}: cannot read as ASC: {exc or type(exc).__name__}") from None


# ---------------------------------------------------------------------------------------------
# BLF
# ---------------------------------------------------------------------------------------------
def _blf(path: str, st: LogStats) -> Iterator[Frame]:
    from can.io import blf as B

    size = os.path.getsize(path)
    if size < B.FILE_HEADER_STRUCT.size:
        raise InputError(f"{path}: not a BLF file ({size} bytes, shorter than the "
                         f"{B.FILE_HEADER_STRUCT.size}-byte header)")
    with open(path, "rb") as fh:
        head = B.FILE_HEADER_STRUCT.unpack(fh.read(B.FILE_HEADER_STRUCT.size))
    if head[0] != b"LOGG" or not B.FILE_HEADER_STRUCT.size <= head[1] <= 4096:
        raise InputError(f"{path}: not a BLF file (no 'LOGG' header of a plausible size)")
    try:
        reader = B.BLFReader(path)
    except (B.BLFParseError, struct.error, ValueError, OSError):
        raise InputError(f"{path}: not a BLF file (no valid 'LOGG' header)") from None
    try:
        declared = int(reader.file_size)
        if declared and size < declared:
            raise InputError(f"{path}: truncated: the header says {declared} bytes, the file has {size}")
        if declared == B.FILE_HEADER_SIZE and size > declared:
            raise InputError(f"{path}: incomplete: the header was never updated (the logger did not "
                             "finish the file)")
        f = reader.file
        base = B.OBJ_HEADER_BASE_STRUCT
        while True:
            pos = f.tell()
            head = f.read(base.size)
            if not head:
                break
            if len(head) < base.size:
                raise InputError(f"{path}: truncated at byte {pos}: an object header is cut off")
            signature, _hs, _hv, obj_size, obj_type = base.unpack(head)
            if signature != b"LOBJ" or obj_size < base.size:
                raise InputError(f"{path}: corrupt at byte {pos}: no object there")
            body = f.read(obj_size - base.size)
            if len(body) < obj_size - base.size:
                if declared and size >= declared:   # the file is as long as it should be
                    raise InputError(f"{path}: corrupt at byte {pos}: an object of {obj_size} bytes "
                                     "runs past the end of the file")
                raise InputError(f"{path}: truncated at byte {pos}: an object of {obj_size} bytes "
                                 f"has {len(body) + base.size}")
            f.read(obj_size % 4)
            if obj_type != B.LOG_CONTAINER:
                continue
            try:
                method, usize = B.LOG_CONTAINER_STRUCT.unpack_from(body)
            except struct.error:
                raise InputError(f"{path}: corrupt at byte {pos}: container header cut off") from None
            payload = body[B.LOG_CONTAINER_STRUCT.size:]
            if method == B.ZLIB_DEFLATE:
                z = zlib.decompressobj()
                try:
                    payload = z.decompress(payload)
                except zlib.error as exc:
                    raise InputError(f"{path}: corrupt at byte {pos}: compressed container: {exc}") from None
                if not z.eof:
                    raise InputError(f"{path}: truncated at byte {pos}: compressed container incomplete")
            elif method != B.NO_COMPRESSION:
                raise InputError(f"{path}: corrupt at byte {pos}: unknown compression method {method}")
            if usize and len(payload) != usize:
                raise InputError(f"{path}: corrupt at byte {pos}: container holds {len(payload)} "
                                 f"bytes, its header says {usize}")
            try:
                for m in reader._parse_container(payload):
                    frame = _data_frame(m, st)
                    if frame is not None:
                        yield frame
            except (B.BLFParseError, struct.error, ValueError, OverflowError) as exc:
                raise InputError(f"{path}: corrupt in the container at byte {pos}: "
                                 f"{exc or type(exc).__name__}") from None
        if reader._tail.strip(b"\x00"):
            raise InputError(f"{path}: truncated: the last object ({len(reader._tail)} bytes) is cut off")
    finally:
        reader.stop()
