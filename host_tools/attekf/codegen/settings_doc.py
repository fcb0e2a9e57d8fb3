"""The settings table of docs/architecture.md, from firmware/att/att_settings_table.h.

The header holds one X-macro row per setting (name, type, defaults, range, check, live,
unit, help); this module parses those rows and writes the Markdown table between the
markers of docs/architecture.md, so that the documentation cannot drift from the code
(``python -m attekf.codegen --check`` compares them).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Dict, List, NamedTuple

HEADER = "firmware/att/att_settings_table.h"
DOC = "docs/architecture.md"
BEGIN = "<!-- settings table: generated from firmware/att/att_settings_table.h by python -m attekf.codegen -->"
END = "<!-- end of the generated settings table -->"
GROUPS = (("ATT_SETTINGS_MAIN", ""), ("ATT_SETTINGS_REST", "rest."), ("ATT_SETTINGS_BIAS", "bias."))


class Row(NamedTuple):
    name: str
    type: str
    default: str
    default_fixed: str
    lo: str
    hi: str
    check: str
    live: bool
    unit: str
    help: str


def _split_args(text: str) -> List[str]:
    """Top-level comma split of a macro argument list; C string literals kept whole (and
    adjacent literals joined)."""
    args, cur, i, depth = [], [], 0, 0
    while i < len(text):
        ch = text[i]
        if ch == '"':
            j = i + 1
            while text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            cur.append(text[i:j + 1])
            i = j + 1
            continue
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
        if ch == "," and depth == 0:
            args.append("".join(cur).strip())
            cur = []
        else:
            cur.append(ch)
        i += 1
    args.append("".join(cur).strip())
    return args


def _string(arg: str) -> str:
    parts = re.findall(r'"((?:[^"\\]|\\.)*)"', arg)
    if not parts:
        raise ValueError(f"{HEADER}: expected a string literal, got {arg!r}")
    return "".join(parts)


def _calls(body: str) -> List[str]:
    """The argument text of every X(...) in body (parentheses and strings respected)."""
    out: List[str] = []
    for m in re.finditer(r"\bX\(", body):
        i, depth, start = m.end(), 1, m.end()
        while depth:
            ch = body[i]
            if ch == '"':
                i += 1
                while body[i] != '"':
                    i += 2 if body[i] == "\\" else 1
            elif ch == "(":
                depth += 1
            elif ch == ")":
                depth -= 1
            i += 1
        out.append(body[start:i - 1])
    return out


def parse(text: str) -> List[Row]:
    """Every row of the three groups, names with their group prefix."""
    rows: List[Row] = []
    for macro, prefix in GROUPS:
        m = re.search(r"#define " + macro + r"\(X\)(.*?)(?=\n#define |\n/\* clang-format on)", text, re.S)
        if m is None:
            raise ValueError(f"{HEADER}: no #define {macro}(X)")
        body = re.sub(r"/\*.*?\*/", "", m.group(1), flags=re.S).replace("\\\n", " ")
        for call in _calls(body):
            a = _split_args(call)
            if len(a) != 10:
                raise ValueError(f"{HEADER}: row {a[:1]} has {len(a)} fields, not 10")
            rows.append(Row(prefix + a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7] == "1",
                            _string(a[8]), _string(a[9])))
    return rows


def _num(text: str) -> str:
    """A number as people read it (float() form: 1e-06 -> 1e-06, 0.0035 -> 0.0035)."""
    v = float(text)
    if v == int(v) and abs(v) < 1e6:
        return str(int(v))
    return f"{v:.6g}"


def table(rows: List[Row]) -> str:
    out = ["| setting | unit | default | range | live | meaning |", "|---|---|---|---|---|---|"]
    for r in rows:
        default = _num(r.default)
        if float(r.default_fixed) != float(r.default):
            default += f" (fixed point {_num(r.default_fixed)})"
        rng = f"{_num(r.lo)} .. {_num(r.hi)}"
        help_ = r.help.replace("|", "\\|")
        out.append(f"| `{r.name}` | {r.unit} | {default} | {rng} | {'yes' if r.live else 'no'} | {help_} |")
    return "\n".join(out)


def build_doc(root: Path) -> Dict[str, str]:
    rows = parse((root / HEADER).read_text())
    doc = (root / DOC).read_text()
    if BEGIN not in doc or END not in doc:
        raise ValueError(f"{DOC}: the markers of the generated settings table are missing")
    head, rest = doc.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    return {DOC: head + BEGIN + "\n" + table(rows) + "\n" + END + tail}
