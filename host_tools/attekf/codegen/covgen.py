"""Arithmetic kernels of the attitude filter's packed covariance (att_cov_gen.[ch]).

``firmware/att/att_cov.c`` (hand-written) owns the storage of ``P`` in float and double: the
45 entries of its lower triangle, ``P_ij`` (i >= j) at ``p[i (i + 1) / 2 + j]``, and every
operation on it. The operations done every step call the straight-line kernels generated
here, where every packed index, sparsity pattern and structural constant is resolved at
generation time (docs/architecture.md, "The covariance interface"):

* ``att_cov_gen_predict``: ``P <- F2 (F1 P F1^T + diag(var, 0, 0)) F2^T`` on the two factors of
  the transition Jacobian (attitude.transition_factors), with the variance of each angle's
  increment ``(D1 P D1^T)_ii``; the old Euler-rate rows, which F2 replaces, are never read;
* ``att_cov_gen_rank1``: the write of a scalar update, ``P_ij - K_i b_j`` (i <= j) with the
  diagonal floored, and ``x + K nu``: ekf_update_scalar's operations in its order (bit-identical);
* ``att_cov_gen_ldl_ok``: the definiteness test, an LDL^T factorisation with one reciprocal
  per pivot (ekf_cov_is_pd's recurrence).

Nothing else: no storage management, no policy, no assembly (att_cov.c has the FPU variants
of the rank-one write).
"""

from __future__ import annotations

from typing import Dict, List, Sequence, Tuple

from . import attitude
from .cprinter import CPP_CLOSE, CPP_OPEN, sparse_entries

N = 9
STATES = attitude.STATE_NAMES
SCRIPT = "host_tools/attekf/codegen/covgen.py"
ANGLES = [3, 4, 5]
RATES = [6, 7, 8]
KEEP = [0, 1, 2, 3, 4, 5]  # the rows and columns F2 reads: body rates and angles


def L(i: int, j: int) -> int:
    """Packed index of P_ij: the lower triangle row by row, P_ij (i >= j) at i (i + 1) / 2 + j."""
    if i < j:
        i, j = j, i
    return i * (i + 1) // 2 + j


NP = L(N - 1, N - 1) + 1


def chain(terms: Sequence[Tuple[str, str]], start: str | None = None) -> str:
    """start + a1 b1 + a2 b2 + ... (evaluated in that order); a term whose factor is '1'
    is added without a multiplication. Without start, the first term begins the sum."""
    expr = start
    for a, b in terms:
        if expr is None:
            expr = b if a == "1" else f"ekf_mul({a}, {b})"
        elif a == "1":
            expr = f"ekf_add({expr}, {b})"
        else:
            expr = f"ekf_mac({expr}, {a}, {b})"
    assert expr is not None
    return expr


class Block:
    """Straight-line C: const locals and raw lines."""

    def __init__(self, indent: str = "    "):
        self.lines: List[str] = []
        self.indent = indent

    def let(self, name: str, expr: str) -> str:
        self.lines.append(f"{self.indent}const ekf_scalar_t {name} = {expr};")
        return name

    def raw(self, line: str) -> None:
        self.lines.append(f"{self.indent}{line}")

    def text(self) -> str:
        return "\n".join(self.lines)


# ---- the prediction --------------------------------------------------------------------------
def predict_kernel() -> str:
    D1, D2 = attitude.transition_factors()
    pat1 = attitude.f1_pattern()
    e2 = sparse_entries(D2)
    assert sorted({i for i, _ in pat1}) == ANGLES and all(j in KEEP for _, j in pat1), \
        "F1 changes the angle rows, from the body rates and angles"
    # F2 replaces its rows: -1 on the diagonal (F2_rr = 0), the rest on the kept columns
    for r in RATES:
        assert [e for (i, j, e) in e2 if i == r and j == r] == [-1], "F2 must not read the old Euler rates"
        assert all(j == r or j in KEEP for (i, j, _) in e2 if i == r)
    d1 = {(i, j): f"d1[{k}]" for k, (i, j) in enumerate(pat1)}
    coef2: Dict[Tuple[int, int], str] = {}
    for k, (i, j, e) in enumerate(e2):
        if i != j:
            coef2[i, j] = "1" if e == 1 else f"d2[{k}]"
            assert e == 1 or not e.is_Number, "F2's constants: 1, and -1 on the diagonal"

    b = Block()
    b.raw("/* P's rows and columns of the body rates and angles (the Euler-rate ones are replaced) */")
    for i in KEEP:
        for j in KEEP:
            if j <= i:
                b.let(f"p{i}{j}", f"p[{L(i, j)}]")

    def P(i: int, j: int) -> str:
        return f"p{max(i, j)}{min(i, j)}"

    b.raw("/* B = D1 P on the kept columns (D1's rows are the angles) */")
    for i in ANGLES:
        for j in KEEP:
            b.let(f"b{i}{j}", chain([(d1[i, k], P(k, j)) for k in KEEP if (i, k) in d1]))
    b.raw("/* the variance of each angle's increment, (D1 P D1^T)_ii */")
    for x, i in enumerate(ANGLES):
        v = chain([(d1[i, k], f"b{i}{k}") for k in KEEP if (i, k) in d1])
        b.raw(f"inc_var[{x}] = ekf_max({v}, EKF_C(0));")
    b.raw("/* A = F1 P = P + B in the angle rows; P1 = A F1^T: the angle block, and the angle rows on the body rates */")
    for i in ANGLES:
        for j in KEEP:
            b.let(f"a{i}{j}", f"ekf_add({P(i, j)}, b{i}{j})")
    q: Dict[Tuple[int, int], str] = {}  # P1 on the kept rows and columns, by name
    for i in KEEP:
        for j in KEEP:
            if j > i:
                continue
            if i in ANGLES and j in ANGLES:
                q[i, j] = b.let(f"q{i}{j}", chain([(d1[j, k], f"a{i}{k}") for k in KEEP if (j, k) in d1],
                                                  start=f"a{i}{j}"))
            elif i in ANGLES:
                q[i, j] = f"a{i}{j}"
            else:
                q[i, j] = P(i, j)
    Q = lambda i, j: q[max(i, j), min(i, j)]  # noqa: E731
    b.raw("/* the rate noise between the factors: G diag(var) G^T = F2 diag(var, 0) F2^T */")
    for i in (0, 1, 2):
        q[i, i] = b.let(f"v{i}", f"ekf_add({P(i, i)}, var[{i}])")
    b.raw("/* R = F2 P1 in the Euler-rate rows, on the kept columns; P2 = R F2^T in the Euler-rate block */")
    for r in RATES:
        for j in KEEP:
            b.let(f"r{r}{j}", chain([(coef2[r, c], Q(c, j)) for c in KEEP if (r, c) in coef2]))
    for r in RATES:
        for t in RATES:
            if t < r:
                continue
            b.let(f"s{t}{r}", chain([(coef2[t, c], f"r{r}{c}") for c in KEEP if (t, c) in coef2]))
    b.raw("/* stores */")
    for i in ANGLES:
        for j in KEEP:
            if j <= i:
                b.raw(f"p[{L(i, j)}] = {Q(i, j)};")
    for i in (0, 1, 2):
        b.raw(f"p[{L(i, i)}] = v{i};")
    for r in RATES:
        for j in KEEP:
            b.raw(f"p[{L(r, j)}] = r{r}{j};")
        for t in RATES:
            if t <= r:
                b.raw(f"p[{L(r, t)}] = s{r}{t};")
    return (
        "void att_cov_gen_predict(ekf_scalar_t p[ATT_COV_NP], const ekf_scalar_t d1[ATT_GEN_F1_NNZ],\n"
        "                         const ekf_scalar_t d2[ATT_GEN_F2_NNZ], const ekf_scalar_t var[3],\n"
        "                         ekf_scalar_t inc_var[3])\n{\n" + b.text() + "\n}\n"
    )


# ---- the write of a scalar update ------------------------------------------------------------
def rank1_kernel() -> str:
    b = Block()
    for i in range(N):
        b.let(f"k{i}", f"ekf_mul(b[{i}], inv_s)")
        b.let(f"b{i}", f"b[{i}]")
    # storage order: row j of the lower triangle holds P_ij, i <= j (ekf_update_scalar's upper
    # triangle, row i, column j): P_ij - K_i b_j
    for j in range(N):
        for i in range(j):
            b.raw(f"p[{L(j, i)}] = ekf_mac(p[{L(j, i)}], ekf_neg(k{i}), b{j});")
        b.raw(f"{{ const ekf_scalar_t v = ekf_mac(p[{L(j, j)}], ekf_neg(k{j}), b{j}); "
              f"p[{L(j, j)}] = (v < var_floor) ? var_floor : v; }}")
    for i in range(N):
        b.raw(f"x[{i}] = ekf_mac(x[{i}], k{i}, nu);")
    return (
        "void att_cov_gen_rank1(ekf_scalar_t p[ATT_COV_NP], ekf_scalar_t x[ATT_N], const ekf_scalar_t b[ATT_N],\n"
        "                       ekf_scalar_t inv_s, ekf_scalar_t nu, ekf_scalar_t var_floor)\n{\n" + b.text() + "\n}\n"
    )


# ---- the definiteness check ------------------------------------------------------------------
def ldl_kernel() -> str:
    """1 if P = L D L^T with every pivot d_j > 0 and d_j >= margin P_jj, else 0 (returns at the
    first pivot that fails): ekf_cov_is_pd's recurrence, with one reciprocal per pivot
    instead of a division per entry."""
    b = Block()
    for j in range(N):
        for k in range(j):
            expr = f"p[{L(j, k)}]"
            for m in range(k):
                expr = f"ekf_mac({expr}, ekf_neg(w{j}_{m}), l{k}_{m})"
            b.let(f"w{j}_{k}", expr)
        d = f"p[{L(j, j)}]"
        for k in range(j):
            b.let(f"l{j}_{k}", f"ekf_mul(w{j}_{k}, r{k})")
            d = f"ekf_mac({d}, ekf_neg(l{j}_{k}), w{j}_{k})"
        b.let(f"d{j}", d)
        b.raw(f"if (!(d{j} > EKF_C(0)) || !(d{j} >= ekf_mul(margin, p[{L(j, j)}]))) {{")
        b.raw("    return 0;")
        b.raw("}")
        if j < N - 1:
            b.let(f"r{j}", f"ekf_div(EKF_C(1), d{j})")
    return "int att_cov_gen_ldl_ok(const ekf_scalar_t p[ATT_COV_NP], ekf_scalar_t margin)\n{\n" + b.text() + \
        "\n    return 1;\n}\n"


DECLS = """/* P <- F2 (F1 P F1^T + diag(var, 0, 0)) F2^T = F P F^T + G diag(var) G^T on packed storage,
 * F1 = I + D1 and F2 = I + D2 with d1, d2 in the order of att_gen_f1_pattern and
 * att_gen_f2_pattern (att_gen_transition_factors; F2's constant entries are taken as such),
 * var the body-rate noise per axis; inc_var[i] = (D1 P D1^T)_ii of the angle rows, evaluated
 * on P before the prediction (>= 0). */
void att_cov_gen_predict(ekf_scalar_t p[ATT_COV_NP], const ekf_scalar_t d1[ATT_GEN_F1_NNZ],
                         const ekf_scalar_t d2[ATT_GEN_F2_NNZ], const ekf_scalar_t var[3],
                         ekf_scalar_t inc_var[3]);

/* The write of a scalar update whose checks passed (att_cov.c): K = b inv_s, P_ij <- P_ij -
 * K_i b_j on the lower triangle (each new variance below var_floor set to it), x <- x + K nu;
 * ekf_update_scalar's operations in its order. */
void att_cov_gen_rank1(ekf_scalar_t p[ATT_COV_NP], ekf_scalar_t x[ATT_N], const ekf_scalar_t b[ATT_N],
                       ekf_scalar_t inv_s, ekf_scalar_t nu, ekf_scalar_t var_floor);

/* 1 if P has an LDL^T factorisation with every pivot d_j > 0 and d_j >= margin P_jj (NaN
 * fails every comparison), else 0, at the first pivot that fails: the recurrence of
 * ekf_cov_is_pd (w_jk = P_jk - sum_m w_jm L_km, L_jk = w_jk / d_k, d_j = P_jj - sum_k L_jk
 * w_jk), with one reciprocal per pivot. */
int att_cov_gen_ldl_ok(const ekf_scalar_t p[ATT_COV_NP], ekf_scalar_t margin);"""


def build() -> Dict[str, str]:
    banner = (
        "/*\n * att_cov_gen - arithmetic kernels of the packed covariance (att_cov.c)\n *\n"
        f" * GENERATED by {SCRIPT}; do not edit. Regenerate with\n"
        " *     python -m attekf.codegen\n"
        " * The test suite fails when this file differs from the script's output.\n */\n"
    )
    header = (banner + "#ifndef ATT_COV_GEN_H\n#define ATT_COV_GEN_H\n\n#include \"att_defs.h\"\n#include \"att_gen.h\"\n\n"
              + CPP_OPEN + "\n" + DECLS + "\n\n" + CPP_CLOSE + "\n#endif /* ATT_COV_GEN_H */\n")
    source = (banner + '#include "att_cov_gen.h"\n\n' + predict_kernel() + "\n" + rank1_kernel() + "\n"
              + ldl_kernel())
    return {"att_cov_gen.h": header, "att_cov_gen.c": source}
