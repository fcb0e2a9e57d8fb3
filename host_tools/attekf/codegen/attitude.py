"""Symbolic derivation of the 9-state attitude model (docs/derivation.md).

State ``x = [p q r  phi theta psi  phid thetad psid]``: body rates (rad/s), ZYX Euler
angles (rad), Euler-angle rates (rad/s). Earth frame ENU (z up); the rotation
``R = Rz(psi) Ry(theta) Rx(phi)`` maps body to earth.

Transition over one step ``dt`` with angular-acceleration noise ``w`` (rad/s, the change of
the body rate over the step):

    omega+    = omega + w                           (body rates: random walk)
    Theta_m   = Theta + dt/2 * Thetadot             (angles half a step ahead)
    Theta+    = Theta + dt * W(phi_m, theta_m) omega (angles: midpoint rule)
    Thetadot+ = W(phi+, theta+) * omega+            (Euler rates from body rates, ZYX kinematics)

The angles integrate the body rate just fused (the gyro sample of the interval ending now)
through W evaluated half a step ahead: the midpoint rule, second order. The first-order rule
Theta+ = Theta + dt * Thetadot lags one sample and drifts by O(dt^2 |omega|^2) per step, tens
of degrees in a few seconds of fast tumbling at 286 Hz (docs/derivation.md, "Transition").

``W`` is the body-rate to Euler-rate map; ``E = W^-1`` (Euler rates to body rates) is
generated too. Every Jacobian below is ``sympy``'s partial derivative of these expressions
with all nine states independent: no ratio of time derivatives appears anywhere.

Trigonometry is not evaluated in the generated code. The caller passes the sines, cosines
and ``sec(theta)`` of the angles the function is evaluated at (``att_trig_t``: for the
transition, of the midpoint angles ``tm`` and of the advanced angles ``t``), computed once
per step in hand-written code that also applies the gimbal-lock clamp (att_model.c).
"""

from __future__ import annotations

import functools
import math
from typing import Dict

import sympy as sp

from . import covprop
from .cprinter import CFunction, render_files, sparse_entries

STATE_NAMES = ["P", "Q", "R", "PHI", "THETA", "PSI", "PHID", "THETAD", "PSID"]

p, q, r = sp.symbols("p q r", real=True)
phi, theta, psi = sp.symbols("phi theta psi", real=True)
phid, thetad, psid = sp.symbols("phid thetad psid", real=True)
dt = sp.Symbol("dt", positive=True)
wp, wq, wr = sp.symbols("wp wq wr", real=True)
X = sp.Matrix([p, q, r, phi, theta, psi, phid, thetad, psid])
NOISE = sp.Matrix([wp, wq, wr])

# Trigonometric terms handed in by the caller (att_trig_t).
sph, cph, sth, cth, secth = sp.symbols("sph cph sth cth secth", real=True)
TRIG = (sph, cph, sth, cth, secth)
TRIG_MID = sp.symbols("sphm cphm sthm cthm secthm", real=True)
mx, my, mz = sp.symbols("mx my mz", real=True)


def euler_rate_map(ph: sp.Expr, th: sp.Expr) -> sp.Matrix:
    """W: body rates -> Euler-angle rates for ZYX angles (singular at cos(theta) = 0)."""
    return sp.Matrix(
        [
            [1, sp.sin(ph) * sp.tan(th), sp.cos(ph) * sp.tan(th)],
            [0, sp.cos(ph), -sp.sin(ph)],
            [0, sp.sin(ph) / sp.cos(th), sp.cos(ph) / sp.cos(th)],
        ]
    )


def body_rate_map(ph: sp.Expr, th: sp.Expr) -> sp.Matrix:
    """E = W^-1: Euler-angle rates -> body rates (p = phid - psid sin(theta), ...)."""
    return sp.Matrix(
        [
            [1, 0, -sp.sin(th)],
            [0, sp.cos(ph), sp.sin(ph) * sp.cos(th)],
            [0, -sp.sin(ph), sp.cos(ph) * sp.cos(th)],
        ]
    )


def rot_x(a: sp.Expr) -> sp.Matrix:
    return sp.Matrix([[1, 0, 0], [0, sp.cos(a), -sp.sin(a)], [0, sp.sin(a), sp.cos(a)]])


def rot_y(a: sp.Expr) -> sp.Matrix:
    return sp.Matrix([[sp.cos(a), 0, sp.sin(a)], [0, 1, 0], [-sp.sin(a), 0, sp.cos(a)]])


def rot_z(a: sp.Expr) -> sp.Matrix:
    return sp.Matrix([[sp.cos(a), -sp.sin(a), 0], [sp.sin(a), sp.cos(a), 0], [0, 0, 1]])


def midpoint_angles() -> tuple:
    """(phi_m, theta_m): roll and pitch half a step ahead, where W is evaluated."""
    return phi + dt / 2 * phid, theta + dt / 2 * thetad


def advanced_angles() -> sp.Matrix:
    """Theta+ = Theta + dt W(phi_m, theta_m) omega (the rate before the noise)."""
    phim, thm = midpoint_angles()
    return sp.Matrix([phi, theta, psi]) + dt * euler_rate_map(phim, thm) * sp.Matrix([p, q, r])


def transition() -> sp.Matrix:
    """f(x, w, dt) as above."""
    omega = sp.Matrix([p, q, r]) + NOISE
    ang = advanced_angles()
    rates = euler_rate_map(ang[0], ang[1]) * omega
    return sp.Matrix([omega[0], omega[1], omega[2], ang[0], ang[1], ang[2], rates[0], rates[1], rates[2]])


def accel_direction() -> sp.Matrix:
    """Unit specific force at rest in the body frame: R^T * (0, 0, 1) (ENU, z up)."""
    return (rot_z(psi) * rot_y(theta) * rot_x(phi)).T * sp.Matrix([0, 0, 1])


def mag_levelled() -> sp.Matrix:
    """Body-frame field rotated into the yaw frame: Ry(theta) Rx(phi) m.

    For an earth field (Bh sin D, Bh cos D, -Bv) (declination D east of north), this is
    (Bh sin(psi + D), Bh cos(psi + D), -Bv): the heading is atan2(x, y) - D.
    """
    return rot_y(theta) * rot_x(phi) * sp.Matrix([mx, my, mz])


def _trig_subs(expr: sp.Expr, ph: sp.Expr, th: sp.Expr, syms: tuple = TRIG) -> sp.Expr:
    """Replace trig functions of (ph, th) by the caller-supplied att_trig_t symbols
    syms = (sph, cph, sth, cth, secth)."""
    s_ph, c_ph, s_th, c_th, sec_th = syms
    expr = sp.sympify(expr)
    expr = expr.subs(
        {
            sp.tan(th): s_th * sec_th,
            sp.sin(ph): s_ph,
            sp.cos(ph): c_ph,
            sp.sin(th): s_th,
        }
    )
    expr = expr.subs(sp.cos(th), c_th)
    expr = expr.replace(
        lambda e: e.is_Pow and e.base == c_th and e.exp.is_Integer and e.exp < 0,
        lambda e: sec_th ** (-e.exp),
    )
    expr = sp.expand(expr)
    leftover = expr.atoms(sp.Function)
    if leftover:
        raise ValueError(f"trig left after substitution: {leftover}")
    return expr


@functools.lru_cache(maxsize=None)
def transition_jacobians() -> tuple:
    """(F, G): df/dx and df/dw at w = 0, trig replaced by att_trig_t symbols (TRIG_MID for
    the midpoint angles, TRIG for the advanced ones).

    Same partial derivatives as ``transition().jacobian(...)``, taken with the chain rule
    through the advanced angles so that sympy never differentiates trig of a nested
    expression: Thetadot+ = W(a, b) omega+ with (a, b) = (phi+, theta+), so
    d Thetadot+/dx = W(a, b) d omega+/dx + dW omega/da d phi+/dx + dW omega/db d theta+/dx.
    """
    phim, thm = midpoint_angles()
    ang = advanced_angles()
    j_ang = ang.jacobian(X).applyfunc(lambda e: _trig_subs(e, phim, thm, TRIG_MID))
    a, b = sp.symbols("a_adv b_adv", real=True)
    omega = sp.Matrix([p, q, r]) + NOISE
    rates = euler_rate_map(a, b) * omega
    j_rates = rates.jacobian(X) + rates.diff(a) * j_ang[0, :] + rates.diff(b) * j_ang[1, :]
    zero_noise = {wp: 0, wq: 0, wr: 0}
    j_rates = j_rates.subs(zero_noise).applyfunc(lambda e: _trig_subs(e, a, b))
    F = sp.zeros(9, 9)
    F[0:3, 0:3] = sp.eye(3)
    F[3:6, :] = j_ang
    F[6:9, :] = j_rates
    G = sp.zeros(9, 3)
    G[0:3, 0:3] = sp.eye(3)
    G[6:9, :] = rates.jacobian(NOISE).subs(zero_noise).applyfunc(lambda e: _trig_subs(e, a, b))
    return F, G


@functools.lru_cache(maxsize=None)
def transition_factors() -> tuple:
    """(D1, D2): F = F2 F1 with F1 = I + D1, F2 = I + D2 (docs/derivation.md, "State
    Jacobian").

    F1 advances the angles and leaves every other state: its angle rows are those of F
    (d Theta+/dx), the rest is the identity. F2 then replaces the Euler rates by
    W(Theta+) omega: its rate rows are d Thetadot+/d(omega, phi+, theta+) (W+ and M+ of the
    table in derivation.md) and zero in the rate columns, the rest is the identity. The
    product is the chain rule that transition_jacobians() writes out, with fewer non-zeros
    per factor than in F (17 + 12 against 39), which is what the covariance propagation
    exploits (covgen.py). Trig as in transition_jacobians()."""
    F, _ = transition_jacobians()
    a, b = sp.symbols("a_adv b_adv", real=True)
    omega = sp.Matrix([p, q, r])
    rates = euler_rate_map(a, b) * omega
    F1 = sp.eye(9)
    F1[3:6, :] = F[3:6, :]
    F2 = sp.eye(9)
    block = sp.zeros(3, 9)
    block[:, 0:3] = rates.jacobian(omega)
    block[:, 3] = rates.diff(a)
    block[:, 4] = rates.diff(b)
    F2[6:9, :] = block.applyfunc(lambda e: _trig_subs(e, a, b))
    if sp.expand(F2 * F1 - F) != sp.zeros(9, 9):
        raise AssertionError("F2 F1 differs from the transition Jacobian")
    return F1 - sp.eye(9), F2 - sp.eye(9)


def _index(i: int) -> str:
    return f"ATT_{STATE_NAMES[i]}"


TRIG_PROLOGUE = [
    "const ekf_scalar_t sph = t->sphi;",
    "const ekf_scalar_t cph = t->cphi;",
    "const ekf_scalar_t sth = t->sth;",
    "const ekf_scalar_t cth = t->cth;",
    "const ekf_scalar_t secth = t->secth;",
]
TRIG_MID_PROLOGUE = [
    "const ekf_scalar_t sphm = tm->sphi;",
    "const ekf_scalar_t cphm = tm->cphi;",
    "const ekf_scalar_t sthm = tm->sth;",
    "const ekf_scalar_t cthm = tm->cth;",
    "const ekf_scalar_t secthm = tm->secth;",
]
STATE_PROLOGUE = [f"const ekf_scalar_t {s.name} = x[{_index(i)}];" for i, s in enumerate(X)]

# Typical magnitudes of the generated code's inputs, for the order of the factors of each
# product (cprinter.to_c: largest first, which keeps the fixed-point build's rounding
# relative to the result): sec(theta) up to 48 at the default gimbal limit, rates a few
# rad/s (up to gyro_range), sines and cosines below 1, steps of milliseconds, the field in uT.
SCALES = {
    **{name: 10.0 for name in ("secth", "secthm")},
    **{name: 0.7 for name in ("sph", "cph", "sth", "cth", "sphm", "cphm", "sthm", "cthm")},
    **{name: 5.0 for name in ("p", "q", "r", "phid", "thetad", "psid")},
    **{name: 1.5 for name in ("phi", "theta", "psi")},
    "dt": 0.005,
    **{name: 50.0 for name in ("mx", "my", "mz")},
}


def _check_against_transition(F: sp.Matrix, G: sp.Matrix) -> None:
    """The chain-rule Jacobians equal sympy's direct derivatives of transition() (checked
    numerically at a few random states; the direct symbolic form is too slow to simplify)."""
    import random

    f = transition()
    direct = sp.lambdify([X, NOISE, dt], (f.jacobian(X), f.jacobian(NOISE)), ["math", "mpmath"])
    rng = random.Random(7)
    for _ in range(5):
        xs = [rng.uniform(-2, 2) for _ in range(9)]
        h = rng.uniform(1e-3, 5e-2)
        vals = {sym: v for sym, v in zip(X, xs)}
        vals[dt] = h
        phm, thm_ = xs[3] + h / 2 * xs[6], xs[4] + h / 2 * xs[7]
        Wm = euler_rate_map(phm, thm_)
        adv = [xs[3 + k] + h * sum(float(Wm[k, j]) * xs[j] for j in range(3)) for k in range(3)]
        for syms, (ph_, th_) in ((TRIG_MID, (phm, thm_)), (TRIG, (adv[0], adv[1]))):
            c = math.cos(th_)
            vals.update(dict(zip(syms, (math.sin(ph_), math.cos(ph_), math.sin(th_), c, 1 / c))))
        Fd, Gd = direct(xs, [0.0, 0.0, 0.0], h)
        for mine, ref in ((F, Fd), (G, Gd)):
            got = mine.subs(vals)
            for i in range(got.rows):
                for j in range(got.cols):
                    assert abs(float(got[i, j]) - float(ref[i, j])) < 1e-9 * (1 + abs(float(ref[i, j]))), (i, j)


def build() -> Dict[str, str]:
    F, G = transition_jacobians()
    _check_against_transition(F, G)
    D = F - sp.eye(9)
    d_entries = sparse_entries(D)
    g_entries = sparse_entries(G)
    # The noise Jacobian is [I; 0; W(phi+, theta+)]: only its Euler-rate block depends on
    # the state, the rest is identity and is applied as such by att_model.c.
    g_block = [(i, j, G[i, j]) for i in range(6, 9) for j in range(3)]
    assert all(e == 1 for i, j, e in g_entries if i < 6 and i == j)
    assert all(i >= 6 or i == j for i, j, e in g_entries)

    W = euler_rate_map(phi, theta)
    Einv = body_rate_map(phi, theta)
    rates = W * sp.Matrix([p, q, r])
    body = Einv * sp.Matrix([phid, thetad, psid])

    h_acc = accel_direction()
    H_acc = h_acc.jacobian(X)
    h_entries = sparse_entries(H_acc)
    assert {j for _, j, _ in h_entries} <= {3, 4}, "accel h depends on roll and pitch only"

    m_lev = mag_levelled()

    fns = []
    fns.append(
        CFunction(
            scales=SCALES,
            name="att_gen_euler_rates",
            doc="Euler-angle rates (rad/s) from body rates w = (p, q, r) (rad/s): W(phi, theta) w.\n"
            "t: trigonometry of (phi, theta).",
            params="const att_trig_t *t, const ekf_scalar_t w[3], ekf_scalar_t out[3]",
            prologue=TRIG_PROLOGUE
            + ["const ekf_scalar_t p = w[0];", "const ekf_scalar_t q = w[1];", "const ekf_scalar_t r = w[2];"],
            outputs=[(f"out[{k}]", _trig_subs(rates[k], phi, theta)) for k in range(3)],
        )
    )
    fns.append(
        CFunction(
            scales=SCALES,
            name="att_gen_body_rates",
            doc="Body rates (rad/s) from Euler-angle rates e = (phid, thetad, psid) (rad/s):\n"
            "E(phi, theta) e, the inverse of att_gen_euler_rates. t: trigonometry of (phi, theta).",
            params="const att_trig_t *t, const ekf_scalar_t e[3], ekf_scalar_t out[3]",
            prologue=TRIG_PROLOGUE
            + [
                "const ekf_scalar_t phid = e[0];",
                "const ekf_scalar_t thetad = e[1];",
                "const ekf_scalar_t psid = e[2];",
            ],
            outputs=[(f"out[{k}]", _trig_subs(body[k], phi, theta)) for k in range(3)],
        )
    )
    fns.append(
        CFunction(
            scales=SCALES,
            name="att_gen_transition_jacobian",
            doc="Non-zero entries of D = F - I, F = df/dx, in the order of att_gen_f_pattern.\n"
            "x: state before the step; dt: step (s); tm: trigonometry of the midpoint angles\n"
            "(phi + dt/2 phid, theta + dt/2 thetad); t: of the advanced angles.",
            params="const att_trig_t *tm, const att_trig_t *t, const ekf_scalar_t x[ATT_N], ekf_scalar_t dt, "
            "ekf_scalar_t d[ATT_GEN_F_NNZ]",
            prologue=TRIG_MID_PROLOGUE + TRIG_PROLOGUE + STATE_PROLOGUE,
            outputs=[(f"d[{k}]", sp.horner(e, wrt=dt)) for k, (_, _, e) in enumerate(d_entries)],
            # no shared dt^2 / 2 (about 5e-5): rounded on its own it lost 20 bits of the
            # Euler-rate rows in fixed point (docs/fixed_point.md, "Accuracy")
            cse_ignore=[dt],
        )
    )
    fns.append(
        CFunction(
            scales=SCALES,
            name="att_gen_noise_jacobian",
            doc="Euler-rate block (rows PHID..PSID) of G = df/dw, row-major 3x3; the body-rate\n"
            "block of G is the identity and the angle block is zero. t: trigonometry of the\n"
            "advanced angles.",
            params="const att_trig_t *t, ekf_scalar_t g[9]",
            prologue=TRIG_PROLOGUE,
            outputs=[(f"g[{(i - 6) * 3 + j}]", e) for i, j, e in g_block],
        )
    )
    fns.append(
        CFunction(
            scales=SCALES,
            name="att_gen_accel_h",
            doc="Predicted accelerometer direction (unit vector, body frame) h(x) = R^T (0,0,1),\n"
            "the specific force of gravity divided by g. t: trigonometry of (phi, theta).",
            params="const att_trig_t *t, ekf_scalar_t h[3]",
            prologue=TRIG_PROLOGUE,
            outputs=[(f"h[{k}]", _trig_subs(h_acc[k], phi, theta)) for k in range(3)],
        )
    )
    fns.append(
        CFunction(
            scales=SCALES,
            name="att_gen_accel_jacobian",
            doc="dh/d(phi, theta) of att_gen_accel_h, row-major 3x2 (all other columns are zero).",
            params="const att_trig_t *t, ekf_scalar_t hj[6]",
            prologue=TRIG_PROLOGUE,
            outputs=[
                (f"hj[{k * 2 + (j - 3)}]", _trig_subs(H_acc[k, j], phi, theta))
                for k in range(3)
                for j in (3, 4)
            ],
        )
    )
    fns.append(
        CFunction(
            scales=SCALES,
            name="att_gen_mag_level",
            doc="Magnetic field m (body frame, any unit) rotated into the yaw frame:\n"
            "Ry(theta) Rx(phi) m. Heading psi = atan2(out[0], out[1]) - declination;\n"
            "dip = atan2(-out[2], |out[0..1]|). t: trigonometry of (phi, theta).",
            params="const att_trig_t *t, const ekf_scalar_t m[3], ekf_scalar_t out[3]",
            prologue=TRIG_PROLOGUE
            + ["const ekf_scalar_t mx = m[0];", "const ekf_scalar_t my = m[1];", "const ekf_scalar_t mz = m[2];"],
            outputs=[(f"out[{k}]", _trig_subs(m_lev[k], phi, theta)) for k in range(3)],
        )
    )

    # The factors F = F2 F1 for the covariance propagation (transition_factors).
    D1, D2 = transition_factors()
    d1_entries = sparse_entries(D1)
    d2_entries = sparse_entries(D2)
    assert [(i, j) for i, j, _ in d1_entries] == [(i, j) for i, j, _ in d_entries if i < 6], \
        "F1's rows are the angle rows of F"
    fns.append(
        CFunction(
            scales=SCALES,
            name="att_gen_transition_factors",
            doc="F = F2 F1, F1 = I + D1, F2 = I + D2 (docs/derivation.md, \"State Jacobian\"): d1 the values\n"
            "of D1 (the angle rows of D) in the order of att_gen_f1_pattern, d2 those of D2 (the\n"
            "Euler-rate rows: W+ on the body rates, M+ on roll and pitch, -1 on the rate itself) in\n"
            "the order of att_gen_f2_pattern. Arguments as for att_gen_transition_jacobian.",
            params="const att_trig_t *tm, const att_trig_t *t, const ekf_scalar_t x[ATT_N], ekf_scalar_t dt, "
            "ekf_scalar_t d1[ATT_GEN_F1_NNZ], ekf_scalar_t d2[ATT_GEN_F2_NNZ]",
            prologue=TRIG_MID_PROLOGUE + TRIG_PROLOGUE + STATE_PROLOGUE,
            outputs=[(f"d1[{k}]", sp.horner(e, wrt=dt)) for k, (_, _, e) in enumerate(d1_entries)]
            + [(f"d2[{k}]", e) for k, (_, _, e) in enumerate(d2_entries)],
            cse_ignore=[dt],
        )
    )

    pattern = ",\n    ".join(f"{{{_index(i)}, {_index(j)}}}" for i, j, _ in d_entries)
    header_extra = (
        '#include "att_defs.h"\n\n'
        "/* Number of structurally non-zero entries of D = F - I. */\n"
        f"#define ATT_GEN_F_NNZ {len(d_entries)}\n\n"
        "/* (row, column) of each entry of D, sorted by row: the pattern for ekf_cov_propagate. */\n"
        "extern const ekf_nz_t att_gen_f_pattern[ATT_GEN_F_NNZ];"
    )
    source_extra = f"const ekf_nz_t att_gen_f_pattern[ATT_GEN_F_NNZ] = {{\n    {pattern}\n}};"
    for name, entries, what in (("f1", d1_entries, "the angle rows"), ("f2", d2_entries, "the Euler-rate rows")):
        pat = ", ".join(f"{{{_index(i)}, {_index(j)}}}" for i, j, _ in entries)
        header_extra += (
            f"\n\n/* Number of structurally non-zero entries of D{name[1]} = F{name[1]} - I ({what}), and their\n"
            f" * (row, column), sorted by row (att_gen_transition_factors). */\n"
            f"#define ATT_GEN_{name.upper()}_NNZ {len(entries)}\n"
            f"extern const ekf_nz_t att_gen_{name}_pattern[ATT_GEN_{name.upper()}_NNZ];"
        )
        source_extra += f"\n\nconst ekf_nz_t att_gen_{name}_pattern[ATT_GEN_{name.upper()}_NNZ] = {{{pat}}};"
    # P <- F P F^T unrolled for this pattern (perf: docs/performance.md)
    prop_decl, prop_def = covprop.emit("att_gen_cov_propagate", 9, "ATT_N", "ATT_GEN_F_NNZ",
                                       [(i, j) for i, j, _ in d_entries], _index, "att_gen_f_pattern")
    header_extra += "\n\n" + prop_decl
    source_extra += "\n\n" + prop_def
    # the same for each factor (the reference covariance implementation, att_cov_ref.c)
    for name, entries in (("f1", d1_entries), ("f2", d2_entries)):
        decl, defn = covprop.emit(f"att_gen_cov_propagate_{name}", 9, "ATT_N", f"ATT_GEN_{name.upper()}_NNZ",
                                  [(i, j) for i, j, _ in entries], _index, f"att_gen_{name}_pattern")
        header_extra += "\n\n" + decl.replace("F = I + D, d: the values of D",
                                                f"F = I + D{name[1]}, d: the values of D{name[1]}")
        source_extra += "\n\n" + defn
    return render_files(
        stem="att_gen",
        title="attitude model: kinematics, Jacobians and measurement functions",
        script="host_tools/attekf/codegen/attitude.py",
        includes=["ekf.h"],
        header_extra=header_extra,
        source_extra=source_extra,
        functions=fns,
    )
