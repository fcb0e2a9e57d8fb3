"""Covariance propagation P <- F P F^T unrolled for a fixed sparsity pattern of D = F - I.

``ekf_cov_propagate`` (firmware/ekf/ekf.c) handles any pattern at run time; a model whose
pattern is fixed can call the function emitted here instead. It performs the same
operations in the same order, so its result is bit-identical to the generic routine's:

  1. the rows of A = F P that differ from P: A_r = P_r + d_k1 P_c1 + d_k2 P_c2 + ... for
     each row r of D (its entries in pattern order); P is exactly symmetric, so column j of
     P is read as row j (contiguous), inside one loop over j;
  2. P+ = A F^T: for i in M (the rows of D) and j not in M, P+_ij = A_ij; for i, j in M
     (j's row not before i's) P+_ij = A_ij + sum_l D_jl A_il, written to both triangles.

Two loops (over the columns in step 1, over the rows of D in step 2) with unrolled bodies: no
pattern is read at run time (docs/performance.md, "Generated propagation").
"""

from __future__ import annotations

from typing import Callable, List, Sequence, Tuple


def _mac_chain(start: str, terms: Sequence[Tuple[str, str]]) -> str:
    """ekf_mac(...ekf_mac(start, a1, b1)..., an, bn): start + a1 b1 + ... in that order."""
    expr = start
    for a, b in terms:
        expr = f"ekf_mac({expr}, {a}, {b})"
    return expr


def emit(
    name: str,
    n: int,
    n_macro: str,
    nnz_macro: str,
    pattern: Sequence[Tuple[int, int]],
    index: Callable[[int], str],
    pattern_name: str,
) -> Tuple[str, str]:
    """(declaration with its comment, definition) of ``void name(P, d)``.

    n: state dimension; pattern: (row, col) of each entry of D, sorted by row; index(i): C
    name of state i; n_macro, nnz_macro: C names of n and of the number of entries.
    """
    rows: List[int] = []
    groups: List[List[int]] = []  # pattern indices of each distinct row
    for k, (r, _c) in enumerate(pattern):
        if k > 0 and r < pattern[k - 1][0]:
            raise ValueError("pattern must be sorted by row")
        if not rows or rows[-1] != r:
            rows.append(r)
            groups.append([])
        groups[-1].append(k)
    nrows = len(rows)
    in_m = set(rows)

    doc = (
        "/*\n"
        " * P <- F P F^T, F = I + D, d: the values of D in the order of "
        f"{pattern_name}.\n"
        " * ekf_cov_propagate() unrolled for this pattern: the same operations in the same order\n"
        " * (bit-identical result) without reading the pattern at run time. P must be exactly\n"
        " * symmetric and stays so. d must be finite (the caller checks).\n"
        " */\n"
    )
    sig = f"void {name}(ekf_scalar_t P[{n_macro} * {n_macro}], const ekf_scalar_t d[{nnz_macro}])"
    lines = [sig, "{"]
    lines.append(
        f"    ekf_scalar_t a[{nrows}][{n_macro}]; /* rows "
        + ", ".join(index(r) for r in rows)
        + " of A = F P */"
    )
    lines.append("    int j;")
    lines.append(f"    for (j = 0; j < {n_macro}; ++j) {{")
    lines.append(f"        const ekf_scalar_t *pj = &P[j * {n_macro}]; /* column j of P (symmetric) */")
    for a, (r, grp) in enumerate(zip(rows, groups)):
        terms = [(f"d[{k}]", f"pj[{index(pattern[k][1])}]") for k in grp]
        lines.append(f"        a[{a}][j] = {_mac_chain(f'pj[{index(r)}]', terms)};")
    lines.append("    }")
    # Step 2 as a loop over the rows of A (a compact body instead of nrows^2 / 2 unrolled
    # entries: flash matters on the target), each (i, j) pair once, j's row not before i's.
    lines.append(
        f"    static const uint8_t rows[{nrows}] = {{" + ", ".join(index(r) for r in rows) + "};"
    )
    lines.append(f"    for (j = 0; j < {nrows}; ++j) {{")
    lines.append("        const ekf_scalar_t *ai = a[j];")
    lines.append("        const int ri = rows[j];")
    lines.append(f"        ekf_scalar_t *pr = &P[ri * {n_macro}];")
    lines.append("        ekf_scalar_t v;")
    for c in range(n):
        if c not in in_m:
            lines.append(f"        pr[{index(c)}] = P[{index(c)} * {n_macro} + ri] = ai[{index(c)}];")
    for b in range(nrows):
        rj = rows[b]
        terms = [(f"d[{k}]", f"ai[{index(pattern[k][1])}]") for k in groups[b]]
        value = _mac_chain(f"ai[{index(rj)}]", terms)
        lines.append(f"        if (j <= {b}) {{")
        lines.append(f"            v = {value};")
        lines.append(f"            pr[{index(rj)}] = v;")
        lines.append(f"            P[{index(rj)} * {n_macro} + ri] = v;")
        lines.append("        }")
    lines.append("    }")
    lines.append("}")
    return doc + sig + ";", "\n".join(lines)
