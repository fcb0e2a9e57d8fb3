"""Helpers shared by the model-library derivations (constacc.py, radar.py, slam.py).

The C printer (cprinter.py) prints +, * and small positive integer powers only: square
roots, divisions and trigonometry are evaluated once by hand-written C code and handed to
the generated functions as plain symbols (``r``, ``inv_r``, ``c``, ``s``, ...). The helpers
below rewrite sympy's derivatives in terms of such symbols and check, numerically, that the
rewritten expression still equals the original derivative.
"""

from __future__ import annotations

import random
from typing import Dict, Iterable, List, Sequence, Tuple

import sympy as sp

from .cprinter import CFunction, sparse_entries


def replace_inverse_powers(expr: sp.Expr, base: sp.Symbol, inv: sp.Symbol) -> sp.Expr:
    """base**(-k) -> inv**k for every negative integer k (inv stands for 1/base)."""
    return sp.sympify(expr).replace(
        lambda e: e.is_Pow and e.base == base and e.exp.is_Integer and e.exp < 0,
        lambda e: inv ** (-e.exp),
    )


def assert_same(
    original: sp.Expr,
    rewritten: sp.Expr,
    bindings: Dict[sp.Symbol, sp.Expr],
    sample: Sequence[sp.Symbol],
    ranges: Dict[sp.Symbol, Tuple[float, float]] | None = None,
    trials: int = 12,
    seed: int = 1,
) -> None:
    """Raise if ``rewritten`` (with its helper symbols bound by ``bindings``, e.g.
    r -> sqrt(dx^2 + dy^2)) differs from ``original`` at random points of ``sample``."""
    rng = random.Random(seed)
    ranges = ranges or {}
    for _ in range(trials):
        point = {s: rng.uniform(*ranges.get(s, (-3.0, 3.0))) for s in sample}
        bound = {k: v.subs(point) for k, v in bindings.items()}
        a = complex(sp.N(sp.sympify(original).subs(point)))
        b = complex(sp.N(sp.sympify(rewritten).subs(bound).subs(point)))
        if abs(a - b) > 1e-9 * max(1.0, abs(a)):
            raise AssertionError(f"rewrite changed the expression: {original} -> {rewritten}")


def csr(matrix: sp.Matrix) -> Tuple[List[int], List[int], List[sp.Expr]]:
    """Compressed sparse rows of the structurally non-zero entries: (row_start, col, value)."""
    entries = sparse_entries(matrix)
    row_start = [0] * (matrix.rows + 1)
    for i, _, _ in entries:
        row_start[i + 1] += 1
    for i in range(matrix.rows):
        row_start[i + 1] += row_start[i]
    return row_start, [j for _, j, _ in entries], [e for _, _, e in entries]


def c_array(ctype: str, name: str, size: str, values: Iterable[str]) -> str:
    body = ", ".join(values)
    return f"const {ctype} {name}[{size}] = {{{body}}};"


def bind(names: Iterable[str], source: str) -> List[str]:
    """Prologue lines ``const ekf_scalar_t name = source[k];`` for CFunction."""
    return [f"const ekf_scalar_t {n} = {source}[{k}];" for k, n in enumerate(names)]


def check_no_functions(exprs: Iterable[sp.Expr]) -> None:
    for e in exprs:
        left = sp.sympify(e).atoms(sp.Function)
        if left:
            raise ValueError(f"function left after substitution: {left} in {e}")


__all__ = [
    "CFunction",
    "assert_same",
    "bind",
    "c_array",
    "check_no_functions",
    "csr",
    "replace_inverse_powers",
]
