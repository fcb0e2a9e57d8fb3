"""Print sympy expressions as C99 for the estimator's scalar layer.

The generated code never uses the C operators + - * / on filter values: every operation is
one of the inline functions of ``firmware/ekf/ekf_scalar.h`` (``ekf_add``, ``ekf_mul``, ...),
and every constant is ``EKF_C(...)``, so the same generated file serves float, double and
any later fixed-point representation. Common subexpressions are shared with ``sympy.cse``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple

import sympy as sp


class CodegenError(ValueError):
    """An expression uses something the scalar layer cannot express."""


def _const(value: sp.Expr) -> str:
    if value.is_Integer:
        return f"EKF_C({int(value)})"
    if value.is_Rational:
        return f"EKF_C({float(value)!r})"
    if value.is_Float:
        return f"EKF_C({float(value)!r})"
    raise CodegenError(f"not a numeric constant: {value}")


def _fold(func: str, parts: Sequence[str]) -> str:
    out = parts[0]
    for part in parts[1:]:
        out = f"{func}({out}, {part})"
    return out


def magnitude(expr: sp.Expr, scales: Dict[str, float]) -> float:
    """Typical size of an expression from the typical sizes of its symbols (1 if unknown):
    products multiply, sums take the largest term."""
    if expr.is_Symbol:
        return scales.get(expr.name, 1.0)
    if expr.is_Number:
        return abs(float(expr))
    if expr.is_Mul:
        out = 1.0
        for arg in expr.args:
            out *= magnitude(arg, scales)
        return out
    if expr.is_Add:
        return max(magnitude(arg, scales) for arg in expr.args)
    if expr.is_Pow and expr.args[1].is_Integer:
        return magnitude(expr.args[0], scales) ** int(expr.args[1])
    return 1.0


def to_c(expr: sp.Expr, scales: Optional[Dict[str, float]] = None) -> str:
    """C text for one expression built from symbols, numbers, +, * and integer powers.

    scales (symbol name -> typical magnitude): if given, the factors of every product are
    multiplied largest first. In fixed point each product is rounded to 1/2 LSB absolute,
    and that error is then scaled by the factors multiplied after it: a small early
    intermediate times sec(theta)^2 and a body rate loses most of its digits, whereas large
    factors first and small ones last shrink the early rounding (docs/fixed_point.md,
    "Accuracy"). Without scales: sympy's canonical order, constant first."""
    if expr.is_Symbol:
        return expr.name
    if expr.is_Number:
        if expr.is_negative:
            return f"ekf_neg({_const(-expr)})"
        return _const(expr)
    if expr.is_Add:
        pos: List[str] = []
        neg: List[str] = []
        for term in sorted(expr.args, key=sp.default_sort_key):
            coeff, rest = term.as_coeff_Mul()
            if coeff.is_negative:
                neg.append(to_c(-term, scales))
            else:
                pos.append(to_c(term, scales))
        if not pos:
            return f"ekf_neg({_fold('ekf_add', neg)})"
        out = _fold("ekf_add", pos)
        for part in neg:
            out = f"ekf_sub({out}, {part})"
        return out
    if expr.is_Mul:
        coeff, rest = expr.as_coeff_Mul()
        if coeff.is_negative:
            return f"ekf_neg({to_c(-expr, scales)})"
        args = sorted(sp.Mul.make_args(rest), key=sp.default_sort_key)
        if scales is None:
            factors = ([_const(coeff)] if coeff != 1 else []) + [to_c(f) for f in args]
        else:
            # a power is its factors repeated, so that dt^2 becomes dt, dt at the end of
            # the product rather than one small, coarsely rounded factor
            flat = []
            for f in args:
                if f.is_Pow and f.args[1].is_Integer and 1 < int(f.args[1]) <= 6:
                    flat.extend([f.args[0]] * int(f.args[1]))
                else:
                    flat.append(f)
            sized = [(magnitude(f, scales), to_c(f, scales)) for f in flat]
            if coeff != 1:
                sized.append((abs(float(coeff)), _const(coeff)))
            factors = [text for _, text in sorted(sized, key=lambda st: -st[0])]  # stable
        return _fold("ekf_mul", factors)
    if expr.is_Pow:
        base, exp = expr.args
        if exp.is_Integer and 1 < int(exp) <= 6:
            b = to_c(base, scales)
            return _fold("ekf_mul", [b] * int(exp))
        raise CodegenError(f"power not supported by the scalar layer: {expr}")
    raise CodegenError(f"unsupported expression ({type(expr).__name__}): {expr}")


@dataclass
class CFunction:
    """One generated C function: named outputs computed from named inputs."""

    name: str
    doc: str
    params: str  # C parameter list
    outputs: List[Tuple[str, sp.Expr]]  # (C lvalue, expression)
    prologue: List[str] = field(default_factory=list)  # C lines that bind inputs to symbols
    scales: Optional[Dict[str, float]] = None  # typical symbol magnitudes: see to_c
    # symbols no shared subexpression may contain (a small one, e.g. dt: see attitude.py)
    cse_ignore: List[sp.Symbol] = field(default_factory=list)

    def render(self) -> str:
        exprs = [e for _, e in self.outputs]
        temps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("t"), optimizations="basic",
                                ignore=self.cse_ignore)
        used = set()
        for e in list(reduced) + [t[1] for t in temps]:
            used |= {s.name for s in e.free_symbols}
        lines = [f"void {self.name}({self.params})", "{"]
        for line in self.prologue:
            # bind only the inputs the expressions use (keeps -Wunused-variable quiet)
            var = line.split("=")[0].split()[-1]
            if var in used:
                lines.append(f"    {line}")
        scales = None if self.scales is None else dict(self.scales)
        for sym, e in temps:
            lines.append(f"    const ekf_scalar_t {sym.name} = {to_c(e, scales)};")
            if scales is not None:
                scales[sym.name] = magnitude(e, scales)
        for (lhs, _), e in zip(self.outputs, reduced):
            lines.append(f"    {lhs} = {to_c(e, scales)};")
        lines.append("}")
        return "\n".join(lines)

    def prototype(self) -> str:
        doc = "\n".join(f" * {line}" if line else " *" for line in self.doc.strip().splitlines())
        return f"/*\n{doc}\n */\nvoid {self.name}({self.params});"


def sparse_entries(matrix: sp.Matrix) -> List[Tuple[int, int, sp.Expr]]:
    """Structurally non-zero entries of a matrix, row-major."""
    out = []
    for i in range(matrix.rows):
        for j in range(matrix.cols):
            e = sp.simplify(matrix[i, j])
            if e != 0:
                out.append((i, j, e))
    return out


# C linkage for C++ users of the generated headers (the pattern of every public header).
CPP_OPEN = '#ifdef __cplusplus\nextern "C" {\n#endif\n'
CPP_CLOSE = '#ifdef __cplusplus\n}\n#endif\n'


def render_files(
    stem: str,
    title: str,
    script: str,
    includes: Sequence[str],
    header_extra: str,
    source_extra: str,
    functions: Sequence[CFunction],
) -> Dict[str, str]:
    """Header and source text of one generated module."""
    guard = stem.upper().replace("/", "_") + "_H"
    banner = (
        f"/*\n * {stem} - {title}\n *\n"
        f" * GENERATED by {script}; do not edit. Regenerate with\n"
        f" *     python -m attekf.codegen\n"
        f" * The test suite fails when this file differs from the script's output.\n */\n"
    )
    inc = "\n".join(f'#include "{i}"' for i in includes)
    header = (
        f"{banner}#ifndef {guard}\n#define {guard}\n\n{inc}\n\n"
        f"{CPP_OPEN}\n{header_extra.strip()}\n\n"
        + "\n\n".join(f.prototype() for f in functions)
        + f"\n\n{CPP_CLOSE}\n#endif /* {guard} */\n"
    )
    source = (
        f'{banner}#include "{stem}.h"\n\n'
        + (source_extra.strip() + "\n\n" if source_extra.strip() else "")
        + "\n\n".join(f.render() for f in functions)
        + "\n"
    )
    return {f"{stem}.h": header, f"{stem}.c": source}
