"""The attitude filter's covariance kernels on packed symmetric storage (att_cov_gen.c).

``firmware/att/att_cov.h`` is the one interface through which the filter touches ``P``. This
generator writes its optimised implementation: ``P`` as the 45 entries of its lower
triangle, and straight-line code for everything the filter does per step, with every
index, sparsity pattern and structural constant resolved here rather than at run time
(docs/architecture.md, "The covariance interface"; figures in docs/performance.md):

* the prediction ``P <- F2 F1 P F1^T F2^T + G diag(var) G^T`` on the two factors of the
  transition Jacobian (attitude.transition_factors), with the variance of each angle's
  increment (``(D P D^T)_ii``) taken from the first factor's own intermediates, the rate
  noise folded in between the factors (``G = F2 [I; 0; 0]``), and nothing computed that the
  second factor overwrites (the old Euler-rate rows and columns);
* the scalar updates with ``H = e_idx`` and with ``H`` on roll and pitch: the gain, the
  checks and the rank-one correction of all 45 entries, the same operations in the same
  order as ``ekf_update_scalar`` (bit-identical results, refusals included);
* the definiteness guard: the diagonal floor and an LDL^T factorisation with one
  reciprocal per pivot, falling back to the diagonal loading of ``ekf_cov_ensure_pd`` only
  when a pivot fails.

The small operations (reset, cap, remap of one state) are short loops over a generated
table of packed indices. The reference implementation with the same semantics is
``att_cov_ref.c`` (full row-major ``P`` on the generic core), selected with
``-DATT_COV_REFERENCE=1``; the fixed-point build has its own (``att_cov_fx.c``).
"""

from __future__ import annotations

from typing import Dict, List, Sequence, Tuple

import sympy as sp

from . import attitude
from .covgen_template import TEMPLATE

N = 9
STATES = attitude.STATE_NAMES
SCRIPT = "host_tools/attekf/codegen/covgen.py"


def L(i: int, j: int) -> int:
    """Packed index of P_ij: the lower triangle row by row, P_ij (i >= j) at i (i + 1) / 2 + j."""
    if i < j:
        i, j = j, i
    return i * (i + 1) // 2 + j


NP = L(N - 1, N - 1) + 1


def mac(acc: str, a: str, b: str) -> str:
    return f"ekf_mac({acc}, {a}, {b})"


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
            expr = mac(expr, a, b)
    assert expr is not None
    return expr


class Block:
    """Straight-line C: const locals and stores, with names for P's entries."""

    def __init__(self, indent: str = "    "):
        self.lines: List[str] = []
        self.indent = indent
        self.loaded: Dict[int, str] = {}

    def p(self, i: int, j: int) -> str:
        """A local holding the input P_ij (loaded once)."""
        k = L(i, j)
        if k not in self.loaded:
            name = f"p{k}"
            self.loaded[k] = name
            self.lines.append(f"{self.indent}const ekf_scalar_t {name} = p[{k}]; /* P({STATES[max(i, j)]}, {STATES[min(i, j)]}) */")
        return self.loaded[k]

    def let(self, name: str, expr: str) -> str:
        self.lines.append(f"{self.indent}const ekf_scalar_t {name} = {expr};")
        return name

    def raw(self, line: str) -> None:
        self.lines.append(f"{self.indent}{line}")

    def text(self) -> str:
        return "\n".join(self.lines)


# ---- the prediction --------------------------------------------------------------------------
def _rows(entries) -> Dict[int, List[Tuple[int, int]]]:
    """row -> [(pattern index, column)], in pattern order."""
    out: Dict[int, List[Tuple[int, int]]] = {}
    for k, (i, j, _) in enumerate(entries):
        out.setdefault(i, []).append((k, j))
    return out


class Acc:
    """Named running sums: the first term assigns, later ones add; declared() lists the
    names for a declaration at function scope."""

    def __init__(self, block: Block, prefix: str):
        self.block, self.prefix, self.started = block, prefix, []

    def _name(self, key) -> str:
        return self.prefix + ("_".join(str(k) for k in key) if isinstance(key, tuple) else str(key))

    def add(self, key, a: str, b_: str) -> None:
        name = self._name(key)
        term = b_ if a == "1" else f"ekf_mul({a}, {b_})"
        if key not in self.started:
            self.started.append(key)
            self.block.raw(f"{name} = {term};")
        elif a == "1":
            self.block.raw(f"{name} = ekf_add({name}, {b_});")
        else:
            self.block.raw(f"{name} = ekf_mac({name}, {a}, {b_});")

    def name(self, key) -> str:
        assert key in self.started, key
        return self._name(key)

    def declared(self) -> List[str]:
        return [self._name(k) for k in self.started]


def predict_kernel() -> str:
    D1, D2 = attitude.transition_factors()
    e1 = attitude.sparse_entries(D1)
    e2 = attitude.sparse_entries(D2)
    rows1, rows2 = _rows(e1), _rows(e2)
    m1, m2 = sorted(rows1), sorted(rows2)
    omega = [0, 1, 2]
    assert m1 == [3, 4, 5], "F1 changes the angles only"
    assert all(i not in m1 + m2 for i in omega), "the body rates are identity rows of both factors"
    # F2 = I + D2 replaces its rows: -1 on the diagonal (F2_rr = 0) and nothing else in its
    # own columns, so the old rows and columns M2 of P1 are never needed
    for r in m2:
        diag = [e for (i, j, e) in e2 if i == r and j == r]
        assert diag == [-1], f"F2 row {r} must not depend on the old Euler rates"
        assert all(c == r or c not in m2 for _, c in rows2[r])
    const2 = {k: e for k, (_, _, e) in enumerate(e2) if e.is_Number}
    assert all(e == 1 for k, e in const2.items() if e2[k][0] != e2[k][1]), "F2's constants: 1, and -1 on the diagonal"
    keep = [j for j in range(N) if j not in m2]  # rows and columns of P1 that F2 reads
    d1_cols = sorted({c for i in m1 for _, c in rows1[i]})
    # step 1 reads, in each column j of A = F1 P that something needs (those P1 keeps and
    # those D1's rows combine), the rows D1 combines and the angle rows
    cols1 = sorted(set(keep) | set(d1_cols))
    rows_in1 = sorted(set(d1_cols) | set(m1))
    # The midpoint rule: the angles depend on the old Euler rates only through the midpoint
    # angles (phi + dt/2 phid, theta + dt/2 thetad), so D1's Euler-rate columns are dt/2 times
    # its roll and pitch columns (checked here) and B = D1 P needs P_phi + dt/2 P_phid and
    # P_theta + dt/2 P_thetad once per column instead of both columns in every row.
    dt = attitude.dt
    mid_pairs = [(3, 6), (4, 7)]
    k_dt = [k for k, (_, _, e) in enumerate(e1) if sp.simplify(e - dt) == 0]
    mid = bool(k_dt) and all(sp.simplify(D1[i, rate] - dt / 2 * D1[i, ang]) == 0
                             for i in m1 for ang, rate in mid_pairs)
    mid_ang = {ang for ang, _ in mid_pairs} if mid else set()
    mid_rate = {rate for _, rate in mid_pairs} if mid else set()
    coef2 = {(r, c): ("1" if k in const2 else f"f{k}") for r in m2 for k, c in rows2[r] if c != r}
    d2_cols = sorted({c for (_, c) in coef2})
    assert set(d2_cols) <= set(keep)

    ci = {c: x for x, c in enumerate(rows_in1)}
    tab1 = [[L(c, j) for c in rows_in1] for j in cols1]
    tab2 = [[L(c, j) for c in d2_cols] + [L(r, j) for r in m2] for j in keep]
    b = Block()
    b.raw("ekf_scalar_t *const p = c->p;")
    b.raw(f"ekf_scalar_t A[{len(m1)}][{len(cols1)}];")
    b.raw("int n;")
    for k in range(len(e1)):
        b.let(f"a{k}", f"d1[{k}]")
    fin = "EKF_C(0)"
    for k in range(len(e1)):
        fin = f"ekf_finite_acc({fin}, a{k})"
    for k in range(len(e2)):
        if k not in const2:
            fin = f"ekf_finite_acc({fin}, d2[{k}])"
    b.raw(f"if (!({fin} == EKF_C(0))) {{")
    b.raw("    return EKF_ERR_NUMERIC; /* a Jacobian entry not finite: nothing written */")
    b.raw("}")
    if mid:
        b.let("h", f"ekf_mul(EKF_C(0.5), a{k_dt[0]})")  # dt / 2: that entry of D1 is dt itself

    # Step 1: B = D1 P and A = P + B in the angle rows, one column per pass (nothing written
    # yet); then the increment variances d1_k B_i,ck (B = A - P), the angle block of
    # P1 = A F1^T and the stores. (Stack: only A is kept, 24 values.)
    b.raw("/* step 1: B = D1 P, A = F1 P = P + B in the angle rows (columns " +
          " ".join(STATES[j] for j in cols1) + ") */")
    b.raw(f"for (n = 0; n < {len(cols1)}; ++n) {{")
    body = Block("        ")
    body.raw("const uint8_t *const ix = att_cov_pred1[n];")
    for c in rows_in1:
        body.let(f"c{c}", f"p[ix[{ci[c]}]]")
    for ang, rate in (mid_pairs if mid else []):
        body.let(f"m{ang}", mac(f"c{ang}", "h", f"c{rate}"))
    for x, i in enumerate(m1):
        terms = [(f"a{k}", f"m{c}" if c in mid_ang else f"c{c}") for k, c in rows1[i] if c not in mid_rate]
        body.let(f"b{i}", chain(terms))
        body.raw(f"A[{x}][n] = ekf_add(c{i}, b{i});")
    b.lines.extend(body.lines)
    b.raw("}")
    n1 = {j: x for x, j in enumerate(cols1)}
    b.raw("/* (D P D^T)_ii of the angle rows: the variance of each angle's increment */")
    for x, i in enumerate(m1):
        # B_i,c = A_i,c - P_i,c (P not written yet): the rounding of A is eps |A|, which
        # the quadratic form scales by d1 ~ dt: far below the variance it is added to
        v = chain([(f"a{k}", f"ekf_sub(A[{x}][{n1[c]}], p[{L(i, c)}])") for k, c in rows1[i]])
        b.raw(f"inc_var[{x}] = ekf_max({v}, EKF_C(0));")
    b.raw("/* P1 = A F1^T: the angle rows, and the body-rate noise (G diag(var) G^T = F2 diag(var, 0) F2^T) */")
    for x, i in enumerate(m1):
        for j in keep:
            if j in m1 and j < i:
                continue
            if j in m1:
                y = m1.index(j)
                v = chain([(f"a{k}", f"A[{x}][{n1[c]}]") for k, c in rows1[j]], start=f"A[{x}][{n1[j]}]")
            else:
                v = f"A[{x}][{n1[j]}]"
            b.raw(f"p[{L(i, j)}] = {v};")
    for i in omega:
        b.raw(f"p[{L(i, i)}] = ekf_add(p[{L(i, i)}], var[{i}]);")
    # Step 2: the rows M2 of P2 = F2 P1 F2^T: R = F2 P1 one kept column per pass (stored at
    # once: nothing reads the old Euler-rate rows any more), then the M2 x M2 block R F2^T
    # from the stored R.
    for k in range(len(e2)):
        if k not in const2:
            b.let(f"f{k}", f"d2[{k}]")
    b.raw("/* step 2: R = F2 P1 in the Euler-rate rows (columns " + " ".join(STATES[j] for j in keep) + ") */")
    b.raw(f"for (n = 0; n < {len(keep)}; ++n) {{")
    body = Block("        ")
    body.raw("const uint8_t *const ix = att_cov_pred2[n];")
    c2 = {c: x for x, c in enumerate(d2_cols)}
    for c in d2_cols:
        body.let(f"c{c}", f"p[ix[{c2[c]}]]")
    for x, r in enumerate(m2):
        body.let(f"r{r}", chain([(coef2[r, c], f"c{c}") for _, c in rows2[r] if c != r]))
        body.raw(f"p[ix[{len(d2_cols) + x}]] = r{r};")
    b.lines.extend(body.lines)
    b.raw("}")
    b.raw("/* P2 = R F2^T in the Euler-rate block */")
    for x, r in enumerate(m2):
        for t in m2:
            if t < r:
                continue
            v = chain([(coef2[t, c], f"p[{L(r, c)}]") for _, c in rows2[t] if c != t])  # R, stored
            b.raw(f"p[{L(r, t)}] = {v};")
    b.raw("return EKF_OK;")

    def table(name: str, rows) -> str:
        body_ = ",\n    ".join("{" + ", ".join(str(v) for v in row) + "}" for row in rows)
        return f"static const uint8_t {name}[{len(rows)}][{len(rows[0])}] = {{\n    {body_}\n}};\n"

    doc = (
        "/* P <- F2 (F1 P F1^T + diag(var, 0)) F2^T = F P F^T + G diag(var) G^T, and the variance\n"
        " * of each angle's increment (D P D^T)_ii from B = D1 P (D's angle rows are D1's).\n"
        f" * Generated from attitude.transition_factors(): {len(e1)} + {len(coef2)} entries. The old\n"
        " * Euler-rate rows and columns, which F2 replaces, are read only where F1 combines them. */\n"
    )
    return (
        "/* Packed indices of the columns the prediction reads: step 1, P(" + ", ".join(STATES[c] for c in rows_in1)
        + ")\n * of columns " + " ".join(STATES[j] for j in cols1) + "; step 2, P1(" + ", ".join(STATES[c] for c in d2_cols)
        + ") and P2(" + ", ".join(STATES[r] for r in m2) + ") of columns " + " ".join(STATES[j] for j in keep) + ". */\n"
        + table("att_cov_pred1", tab1) + table("att_cov_pred2", tab2) + "\n"
        + doc + "ekf_status_t att_cov_predict(att_cov_t *c, const ekf_scalar_t d1[ATT_GEN_F1_NNZ],\n"
        "                             const ekf_scalar_t d2[ATT_GEN_F2_NNZ], const ekf_scalar_t var[3],\n"
        "                             ekf_scalar_t inc_var[3])\n{\n" + b.text() + "\n}\n"
    )


# ---- the scalar update -------------------------------------------------------------------------
def update_common() -> str:
    """Gain, checks and the rank-one correction, given b = P H^T and h b: ekf_update_scalar's
    operations in its order, unrolled for n = 9 on packed storage."""
    chk = Block("    ")
    for i in range(N):
        # one state at a time, so that few values are live at once; the gain is formed again
        # below (the same operation, the same value)
        chk.raw(f"{{ /* {STATES[i]} */")
        chk.raw(f"    const ekf_scalar_t k = ekf_mul(b[{i}], inv_s);")
        chk.raw(f"    const ekf_scalar_t v = ekf_mac(p[{L(i, i)}], ekf_neg(k), b[{i}]);")
        chk.raw(f"    bad = ekf_finite_acc(ekf_finite_acc(bad, ekf_mac(x[{i}], k, nu)), v);")
        chk.raw("    neg |= sign_word(v);")
        chk.raw("}")
    upd = Block("        ")
    for i in range(N):
        upd.raw(f"const ekf_scalar_t k{i} = ekf_mul(b[{i}], inv_s), b{i} = b[{i}];")
    # storage order: row j of the lower triangle holds P_ij, i <= j (ekf_update_scalar's upper
    # triangle, row i, column j): P_ij - K_i b_j
    for j in range(N):
        for i in range(j):
            upd.raw(f"p[{L(j, i)}] = ekf_mac(p[{L(j, i)}], ekf_neg(k{i}), b{j});")
        upd.raw(f"{{ const ekf_scalar_t v = ekf_mac(p[{L(j, j)}], ekf_neg(k{j}), b{j}); "
                f"p[{L(j, j)}] = (v < var_floor) ? var_floor : v; }}")
    for i in range(N):
        upd.raw(f"x[{i}] = ekf_mac(x[{i}], k{i}, nu);")
    # The same on a single-precision FPU (Cortex-M4F, M7, M33): each row of the lower
    # triangle is contiguous, so it is loaded and stored with one VLDM / VSTM instead of an
    # VLDR / VSTR per entry (the compiler does not combine them); VMLS and VMLA round the
    # product like the C above (not fused), so both give the same bits (firmware_equals_host).
    asm = ["vldmia %[x], {s0-s8}"]
    asm += [f"vmla.f32 s{i}, %[k{i}], %[nu]" for i in range(N)]
    asm += ["vstmia %[x], {s0-s8}"]
    for j in range(N):
        regs = "s0" if j == 0 else f"s0-s{j}"
        asm.append(f"vldmia %[p], {{{regs}}}")
        asm += [f"vmls.f32 s{i}, %[k{i}], %[b{j}]" for i in range(j + 1)]
        asm += [f"vcmpe.f32 s{j}, %[fl]", "vmrs APSR_nzcv, fpscr", "it mi", f"vmovmi.f32 s{j}, %[fl]"]
        asm.append(f"vstmia %[p]!, {{{regs}}}")
    asm_text = "\n".join(f'            "{a}\\n\\t"' for a in asm)
    ins = ", ".join([f'[k{i}] "t"(k{i})' for i in range(N)] + [f'[b{i}] "t"(b{i})' for i in range(N)]
                    + ['[fl] "t"(var_floor)', '[nu] "t"(nu)', '[x] "r"(x)'])
    clob = ", ".join(f'"s{i}"' for i in range(N)) + ', "cc", "memory"'
    vfp = Block("        ")
    for i in range(N):
        vfp.raw(f"const ekf_scalar_t k{i} = ekf_mul(b[{i}], inv_s), b{i} = b[{i}];")
    vfp.raw("ekf_scalar_t *pp = p;")
    vfp.raw("__asm__ volatile(")
    vfp.lines.append(asm_text)
    vfp.raw('    : [p] "+r"(pp)')
    vfp.raw(f"    : {ins}")
    vfp.raw(f"    : {clob});")
    # The same with SSE on x86-64 (float): a row's off-diagonal entries four at a time with
    # MULPS / SUBPS, which round each lane like MULSS / SUBSS (P_ij - K_i b_j is the value of
    # P_ij + (-K_i) b_j): the same bits as the C above, in about half the instructions.
    sse = Block("        ")
    sse.raw("const __m128 vs = _mm_set1_ps(inv_s), vnu = _mm_set1_ps(nu);")
    sse.raw("const __m128 k03 = _mm_mul_ps(_mm_loadu_ps(&b[0]), vs), k47 = _mm_mul_ps(_mm_loadu_ps(&b[4]), vs);")
    sse.raw("ekf_scalar_t k[ATT_N];")
    sse.raw("_mm_storeu_ps(&k[0], k03);")
    sse.raw("_mm_storeu_ps(&k[4], k47);")
    sse.raw("k[8] = ekf_mul(b[8], inv_s);")
    kv = ["k03", "k47"]
    for j in range(N):
        sse.raw(f"{{ const ekf_scalar_t bj = b[{j}];")
        chunks = j // 4
        if chunks:
            sse.raw("    const __m128 vb = _mm_set1_ps(bj);")
        for c_ in range(chunks):
            m = L(j, 4 * c_)
            sse.raw(f"    _mm_storeu_ps(&p[{m}], _mm_sub_ps(_mm_loadu_ps(&p[{m}]), _mm_mul_ps({kv[c_]}, vb)));")
        for i in range(4 * chunks, j):
            sse.raw(f"    p[{L(j, i)}] = ekf_sub(p[{L(j, i)}], ekf_mul(k[{i}], bj));")
        sse.raw(f"    {{ const ekf_scalar_t v = ekf_sub(p[{L(j, j)}], ekf_mul(k[{j}], bj)); "
                f"p[{L(j, j)}] = (v < var_floor) ? var_floor : v; }} }}")
    sse.raw("_mm_storeu_ps(&x[0], _mm_add_ps(_mm_loadu_ps(&x[0]), _mm_mul_ps(k03, vnu)));")
    sse.raw("_mm_storeu_ps(&x[4], _mm_add_ps(_mm_loadu_ps(&x[4]), _mm_mul_ps(k47, vnu)));")
    sse.raw("x[8] = ekf_mac(x[8], k[8], nu);")
    return f"""/* The rest of ekf_update_scalar once b = P H^T and h b are formed, for n = 9 on packed
 * storage: S, its refusal, the gate, the gain and every check before the first write, then
 * P - K b^T (P_ij - K_i b_j for i <= j, the diagonal floored) and x + K nu. The same
 * operations on the same values as ekf_update_scalar: bit-identical results. */
static ekf_status_t update_common(att_cov_t *c, ekf_scalar_t x[ATT_N], const ekf_scalar_t b[ATT_N],
                                  ekf_scalar_t hb, ekf_scalar_t nu, ekf_scalar_t r_var,
                                  ekf_scalar_t gate, ekf_scalar_t var_floor, ekf_innov_t *info)
{{
    ekf_scalar_t *const p = c->p;
    const ekf_scalar_t s = ekf_add(hb, r_var);
    ekf_scalar_t inv_s, bad;
    uint32_t neg = 0u; /* bit 31: a new variance negative (or -0) */
    if (info != NULL) {{
        info->innovation = nu;
        info->variance = s;
    }}
    if (!ekf_isfinite(s) || !(s >= r_var) || !(s > EKF_C(0))) {{
        return EKF_ERR_NUMERIC; /* H P H^T < 0: P is not positive semi-definite along H */
    }}
    if (ekf_gate_test(nu, s, gate, info) == EKF_GATED) {{
        return EKF_GATED; /* the gate of ekf_update_scalar, the same function */
    }}
    /* the gain, the new state and the new variances, checked before anything is written:
     * finite, and no variance negative beyond rounding */
    inv_s = ekf_div(EKF_C(1), s);
    bad = EKF_C(0);
{chk.text()}
    if (!(bad == EKF_C(0)) || ((neg >> 31) != 0u && indefinite(p, b, inv_s))) {{
        return EKF_ERR_NUMERIC;
    }}
#if ATT_COV_VFP_SP
    {{
{vfp.text()}
    }}
#elif ATT_COV_SSE
    {{
{sse.text()}
    }}
#else
    {{
{upd.text()}
    }}
#endif
    return EKF_OK;
}}
"""


# ---- the definiteness check ------------------------------------------------------------------
def ldl_kernel() -> str:
    """1 if P = L D L^T with every pivot d_j > 0 and d_j >= margin P_jj, else 0 (returns at the
    first pivot that fails): ekf_cov_is_pd's recurrence, with one reciprocal per pivot
    instead of a division per entry."""
    b = Block()
    for j in range(N):
        for k in range(j):
            terms = [(f"w{j}_{m}", f"l{k}_{m}") for m in range(k)]
            expr = f"p[{L(j, k)}]"
            for a_, b_ in terms:
                expr = mac(expr, f"ekf_neg({a_})", b_)
            b.let(f"w{j}_{k}", expr)
        d = f"p[{L(j, j)}]"
        for k in range(j):
            b.let(f"l{j}_{k}", f"ekf_mul(w{j}_{k}, r{k})")
            d = mac(d, f"ekf_neg(l{j}_{k})", f"w{j}_{k}")
        b.let(f"d{j}", d)
        b.raw(f"if (!(d{j} > EKF_C(0)) || !(d{j} >= ekf_mul(margin, p[{L(j, j)}]))) {{")
        b.raw("    return 0;")
        b.raw("}")
        if j < N - 1:
            b.let(f"r{j}", f"ekf_div(EKF_C(1), d{j})")
    return (
        "/* 1 if P has an LDL^T factorisation with every pivot d_j > 0 and d_j >= margin P_jj (NaN\n"
        " * fails every comparison), else 0, at the first pivot that fails: the recurrence of\n"
        " * ekf_cov_is_pd (w_jk = P_jk - sum_m w_jm L_km, L_jk = w_jk / d_k, d_j = P_jj - sum_k L_jk\n"
        " * w_jk), straight-line, with one reciprocal per pivot. */\n"
        "static int ldl_ok(const ekf_scalar_t p[ATT_COV_NP], ekf_scalar_t margin)\n{\n"
        + b.text()
        + "\n    return 1;\n}\n"
    )


# ---- the file ----------------------------------------------------------------------------------
def _table() -> str:
    rows = ",\n    ".join("{" + ", ".join(str(L(i, j)) for j in range(N)) + "}" for i in range(N))
    return (
        "/* Packed index of P_ij for any i, j (row i of P: att_cov_row[i][0..8]). */\n"
        f"static const uint8_t att_cov_row[ATT_N][ATT_N] = {{\n    {rows}\n}};\n"
    )


def unit_gather() -> str:
    return "\n".join(f"    b[{i}] = c->p[row[{i}]];" for i in range(N))


def tilt_b() -> str:
    return "\n".join(f"    b[{i}] = ekf_mac(ekf_mul(p[{L(i, 3)}], h_phi), p[{L(i, 4)}], h_theta);" for i in range(N))


def guard_diag() -> str:
    """Straight-line test of the guard's fast path: every variance finite and >= the floor."""
    lines = [f"    acc = ekf_finite_acc(acc, p[{L(i, i)}]);" for i in range(N)]
    lines.append("    low = " + " || ".join(f"!(p[{L(i, i)}] >= var_floor)" for i in range(N)) + ";")
    return "\n".join(lines)


def build() -> Dict[str, str]:
    text = TEMPLATE.format(script=SCRIPT, np=NP, table=_table(), predict=predict_kernel(), tilt_b=tilt_b(), unit_gather=unit_gather(), guard_diag=guard_diag(),
                           update_common=update_common(), ldl=ldl_kernel())
    return {"att_cov_gen.c": text}
