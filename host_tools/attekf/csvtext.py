"""Reading the headed CSV files of the host tools (recordings, estimator outputs) into float
columns, with every problem reported as an InputError naming the file, the line and the
column.

What spreadsheets and other programs write is accepted where it is unambiguous: a UTF-8
byte-order mark, CRLF line ends, quoted cells, blanks around cells, blank lines. What is
ambiguous is refused with the reason: another delimiter (';' or tab, as spreadsheets set
to a decimal comma write), UTF-16 text, bytes that are not UTF-8.

Lines starting with '#' before the header are comments; ``# key: value`` comments are
returned as (key, value) pairs, in file order (attekf sim writes its generator, gyro bias
and one ``# episode: KIND START_S STOP_S`` line per disturbance episode there). Written
comment lines stay short (COMMENT_MAX characters): other readers of these files, such as the
firmware's host build (firmware/target/hal_target.c), take lines of at most 1023 characters.
"""

from __future__ import annotations

import codecs
import csv
import math
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .errors import InputError

PROGRESS_ROWS = 10000  # data lines between progress callbacks
COMMENT_MAX = 200      # characters of a written '# key: value' line
DELIMITERS = {";": "';'", "\t": "tab"}


def read_text_lines(path: str) -> List[str]:
    """The lines of a UTF-8 text file (BOM removed); InputError for anything else."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)) and _is_utf16_text(raw):
        raise InputError(f"{path}: UTF-16 text; save it as UTF-8 (spreadsheets: 'CSV UTF-8')")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise InputError(f"{path}: line {line}: not a text file: byte 0x{raw[exc.start]:02x} at "
                         f"offset {exc.start} is not UTF-8") from None
    if "\x00" in text:
        line = text.count("\n", 0, text.index("\x00")) + 1
        raise InputError(f"{path}: line {line}: NUL byte: not a text file")
    return text.splitlines()


def _is_utf16_text(raw: bytes) -> bool:
    try:
        text = raw.decode("utf-16")
    except UnicodeDecodeError:
        return False
    head = text[:4096]   # a numeric table: (almost) all ASCII once decoded
    return bool(head) and sum(c.isascii() and (c.isprintable() or c in "\r\n\t") for c in head) >= 0.9 * len(head)


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def _split(line: str) -> List[str]:
    return next(csv.reader([line]))


def _delimiter_hint(line: str) -> str:
    for d, name in DELIMITERS.items():
        if d in line:
            return (f" (the line is separated by {name}; columns must be separated by ',' and "
                    "decimals written with '.')")
    return ""


def parse_csv(path: str, required: Sequence[str], optional_groups: Sequence[Sequence[str]],
              allow_empty: Dict[str, str], only_known: Optional[Sequence[str]] = None,
              keep_other: bool = False, progress: Optional[Callable[[int], None]] = None) -> tuple:
    """Reads a headed CSV into float columns.

    required: columns that must be present; optional_groups: column groups present all
    together or not at all. allow_empty: column -> group name; an empty cell in such a column
    reads as NaN (then the whole group of that row must be empty); every other empty or
    non-numeric cell of a known column is an error naming the line and the column.
    only_known: parse just these columns, ignore the others; else every column, and with
    keep_other the columns outside required/groups/allow_empty are read leniently (empty =
    NaN; a column holding text is left out). Returns (columns dict name -> float array,
    header list, line numbers array, list of (key, value) from '# key: value' comments).
    """
    lines = read_text_lines(path)
    meta: List[Tuple[str, str]] = []
    header_idx = None
    for i, line in enumerate(lines):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            key, sep, value = s[1:].partition(":")
            if sep and key.strip() and " " not in key.strip():
                meta.append((key.strip(), value.strip()))
            continue
        header_idx = i
        break
    if header_idx is None:
        raise InputError(f"{path}: empty file (a header line is required)")
    hline = header_idx + 1
    header = [h.strip() for h in _split(lines[header_idx])]
    if len(header) == 1 and any(d in header[0] for d in DELIMITERS):
        raise InputError(f"{path}: line {hline}: no ',' in the header{_delimiter_hint(header[0])}")
    if _is_number(header[0]):
        raise InputError(f"{path}: line {hline}: no header (first line is numeric); "
                         f"the first line must name the columns, e.g. {','.join(required)}")
    if len(set(header)) != len(header):
        dup = sorted({h for h in header if header.count(h) > 1})
        raise InputError(f"{path}: line {hline}: duplicate column(s) {', '.join(dup)}")
    missing = [c for c in required if c not in header]
    if missing:
        raise InputError(f"{path}: line {hline}: missing column(s) {', '.join(missing)} "
                         f"(header has: {', '.join(header)})")
    for group in optional_groups:
        present = [c for c in group if c in header]
        if present and len(present) != len(group):
            absent = [c for c in group if c not in header]
            raise InputError(f"{path}: line {hline}: column(s) {', '.join(absent)} missing "
                             f"(needed together with {', '.join(present)})")
    strict = set(required) | {c for g in optional_groups for c in g} | set(allow_empty)
    if only_known is not None:
        wanted = [c for c in header if c and c in only_known]
    else:
        wanted = [c for c in header if c and (c in strict or keep_other)]
    lenient = {c for c in wanted if c not in strict and only_known is None}
    index = {c: header.index(c) for c in wanted}
    rows: List[List[float]] = []
    line_numbers: List[int] = []
    text_columns: Dict[str, int] = {}
    ncol = len(header)
    for i in range(header_idx + 1, len(lines)):
        if progress is not None and (i - header_idx) % PROGRESS_ROWS == 0:
            progress(PROGRESS_ROWS)
        line = lines[i]
        if not line.strip():
            continue  # blank lines (e.g. a trailing newline) carry no sample
        lineno = i + 1
        try:
            cells = _split(line)
        except csv.Error as exc:
            raise InputError(f"{path}: line {lineno}: {exc}") from None
        if len(cells) != ncol:
            raise InputError(f"{path}: line {lineno}: {len(cells)} fields, header has {ncol}"
                             f"{_delimiter_hint(line) if len(cells) < ncol else ''}")
        values = []
        for name in wanted:
            cell = cells[index[name]].strip()
            if cell == "":
                if name in allow_empty or name in lenient:
                    values.append(math.nan)
                    continue
                raise InputError(f"{path}: line {lineno}: column {name}: empty cell")
            try:
                v = float(cell)
            except ValueError:
                if name in lenient:
                    text_columns.setdefault(name, lineno)
                    values.append(math.nan)
                    continue
                raise InputError(f"{path}: line {lineno}: column {name}: "
                                 f"'{cell}' is not a number") from None
            if not math.isfinite(v):
                if name in lenient:
                    values.append(math.nan)
                    continue
                raise InputError(f"{path}: line {lineno}: column {name}: '{cell}' is not finite "
                                 "(leave the cell empty where a value may be absent)")
            values.append(v)
        rows.append(values)
        line_numbers.append(lineno)
    if not rows:
        raise InputError(f"{path}: no data rows after the header (line {hline})")
    data = np.asarray(rows, dtype=np.float64)
    cols = {name: data[:, k] for k, name in enumerate(wanted) if name not in text_columns}
    lines_arr = np.asarray(line_numbers)
    _check_groups(path, cols, allow_empty, lines_arr)
    return cols, header, lines_arr, meta


def _check_groups(path: str, cols: Dict[str, np.ndarray], allow_empty: Dict[str, str],
                  lines_arr: np.ndarray) -> None:
    """A group of optional cells is empty all together or not at all."""
    groups: Dict[str, List[str]] = {}
    for name, g in allow_empty.items():
        if name in cols:
            groups.setdefault(g, []).append(name)
    for g, names in groups.items():
        empty = np.stack([np.isnan(cols[n]) for n in names], axis=1)
        partial = np.any(empty, axis=1) & ~np.all(empty, axis=1)
        if partial.any():
            k = int(np.argmax(partial))
            which = [n for n, e in zip(names, empty[k]) if e]
            raise InputError(f"{path}: line {lines_arr[k]}: column {which[0]}: empty cell while "
                             f"other {g} cells of the row are set (all empty or all set)")


def comment_lines(meta: Dict[str, object]) -> List[Tuple[str, str]]:
    """(key, value) pairs of metadata to write as '# key: value' lines: the entries whose
    line fits in COMMENT_MAX characters (longer ones, e.g. attekf sim's full settings, are
    kept by HDF5 files only)."""
    out = []
    for k, v in meta.items():
        text = " ".join(str(v).split())
        if k and " " not in k and ":" not in k and len(k) + len(text) + 4 <= COMMENT_MAX:
            out.append((k, text))
    return out
