"""Facts that docs/architecture.md states about the built code, checked against the code: the
size of the variables the contract copies (`att_vars_t`, one copy per call) in each build."""

from __future__ import annotations

import re
from pathlib import Path

from attekf import native

DOC = Path(__file__).resolve().parents[2] / "docs" / "architecture.md"


def test_stated_sizes_of_the_saved_copy():
    text = " ".join(DOC.read_text(encoding="utf-8").split())
    m = re.search(r"`sizeof\(att_vars_t\)` is ([\d,]+) bytes in float, ([\d,]+) in double and ([\d,]+) in fixed point",
                  text)
    assert m, "docs/architecture.md no longer states sizeof(att_vars_t) in the expected words"
    stated = [int(g.replace(",", "")) for g in m.groups()]
    built = [native.load(s).module.VARS_SIZE for s in ("float", "double", "fixed")]
    assert stated == built, f"docs/architecture.md states {stated} bytes, the builds have {built}"
