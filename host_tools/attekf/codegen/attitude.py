"""Symbolic derivation of the 9-state attitude model (docs/derivation.md).

State ``x = [p q r  phi theta psi  phid thetad psid]``: body rates (rad/s), ZYX Euler
angles (rad), Euler-angle rates (rad/s). Earth frame ENU (z up); the rotation
``R = Rz(psi) Ry(theta) Rx(phi)`` maps body to earth.

Transition over one step ``dt`` with rate noise ``w`` (rad/s, the change of the body rate
over the step), exact for a body rate that is constant over the step:

    omega+    = omega + w                                     (body rates: random walk)
    R(Theta+) = R(Theta) Exp([omega dt]x)                      (the rotation, composed exactly)
    Thetadot+ = W(phi+, theta+) omega+                         (Euler rates, ZYX kinematics)

Theta+ is read off the composed rotation (att_model.c). Its partial derivatives follow from
R(Theta + dTheta) = R(Theta) Exp([E(Theta) dTheta]x) (a change of the angles is the body
rotation E dTheta) and Exp([(u + du)]x) = Exp([u]x) Exp([Jr(u) du]x) (Jr: the right Jacobian
of SO(3)):

    d Theta+ / d Theta = W(Theta+) C^T E(Theta),    d Theta+ / d omega = W(Theta+) Jr(omega dt) dt

with C = Exp([omega dt]x). The psi column of the first is e_psi exactly (E's psi column is the
earth's vertical in body axes, which C^T carries to the new body axes and W maps back to
psi). ``_check_transition`` compares these with central differences of the composed
rotation at random states when the code is generated; tests/c/test_jacobians.c does the same
for the C code.

``W`` is the body-rate to Euler-rate map; ``E = W^-1`` (Euler rates to body rates) is
generated too. Every other Jacobian below is ``sympy``'s partial derivative with all nine
states independent: no ratio of time derivatives appears anywhere.

Trigonometry, C and Jr dt are not evaluated in the generated code. The caller passes the
sines, cosines and ``sec(theta)`` of the angles a function is evaluated at (``att_trig_t``:
for the transition, of the angles before the step ``t0`` and of the advanced angles ``t``)
and the 3x3 matrices C and Jr dt, computed once per step in hand-written code that also
applies the gimbal-lock clamp to sec(theta) (att_model.c).
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
TRIG0 = sp.symbols("sph0 cph0 sth0 cth0 secth0", real=True)
# C = Exp([omega dt]x) and JD = Jr(omega dt) dt, row-major (att_model_rotation).
C = sp.Matrix(3, 3, sp.symbols("c0:9", real=True))
JD = sp.Matrix(3, 3, sp.symbols("j0:9", real=True))
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


def _w_sym(t: tuple) -> sp.Matrix:
    """W with the caller's trig symbols t = (sph, cph, sth, cth, secth)."""
    s_ph, c_ph, s_th, _, sec_th = t
    return sp.Matrix([[1, s_ph * s_th * sec_th, c_ph * s_th * sec_th], [0, c_ph, -s_ph],
                      [0, s_ph * sec_th, c_ph * sec_th]])


def _e_sym(t: tuple) -> sp.Matrix:
    """E = W^-1 with the caller's trig symbols."""
    s_ph, c_ph, s_th, c_th, _ = t
    return sp.Matrix([[1, 0, -s_th], [0, c_ph, s_ph * c_th], [0, -s_ph, c_ph * c_th]])


ANGLES = (3, 4, 5)  # phi, theta, psi
F1_COLS = (0, 1, 2, 3, 4, 5)  # the columns of F1's angle rows: body rates and angles


@functools.lru_cache(maxsize=None)
def transition_factors() -> tuple:
    """(D1, D2): F = F2 F1 with F1 = I + D1, F2 = I + D2 (docs/derivation.md, "State
    Jacobian").

    F1 advances the angles and leaves every other state: its angle rows are d Theta+/dx,
    W(Theta+) Jr dt on the body rates, W(Theta+) C^T E(Theta) on roll and pitch, e_psi on the
    heading and zero on the Euler rates (the composed rotation does not depend on them). F2
    then replaces the Euler rates by W(Theta+) omega: its rate rows are
    d Thetadot+/d(omega, phi+, theta+) and zero in the rate columns; the rest is the identity.
    Trig of the angles before the step: TRIG0; of the advanced angles: TRIG; C and JD."""
    w_adv = _w_sym(TRIG)
    ang_omega = w_adv * JD
    ang_theta = w_adv * C.T * _e_sym(TRIG0)
    F1 = sp.eye(9)
    F1[3:6, 0:3] = ang_omega
    F1[3:6, 3:5] = ang_theta[:, 0:2]  # the psi column stays e_psi (module docstring)
    a, b = sp.symbols("a_adv b_adv", real=True)
    omega = sp.Matrix([p, q, r])
    rates = euler_rate_map(a, b) * omega
    F2 = sp.eye(9)
    block = sp.zeros(3, 9)
    block[:, 0:3] = rates.jacobian(omega)
    block[:, 3] = rates.diff(a)
    block[:, 4] = rates.diff(b)
    F2[6:9, :] = block.applyfunc(lambda e: _trig_subs(e, a, b))
    return F1 - sp.eye(9), F2 - sp.eye(9)


@functools.lru_cache(maxsize=None)
def transition_jacobians() -> tuple:
    """(F, G): df/dx = F2 F1 and df/dw at w = 0 (G = [I; 0; W(Theta+)]: the noise enters the
    body rates after the angles have moved, and the Euler rates through W(Theta+))."""
    D1, D2 = transition_factors()
    F = sp.expand((sp.eye(9) + D2) * (sp.eye(9) + D1))
    G = sp.zeros(9, 3)
    G[0:3, 0:3] = sp.eye(3)
    G[6:9, :] = _w_sym(TRIG)
    return F, G


def f1_pattern() -> list:
    """(row, column) of D1's entries: every angle row on F1_COLS (the heading column is zero
    in the Euler-angle coordinates, but an entry of the pattern: the covariance kernels take
    any angle rows of this shape)."""
    return [(i, j) for i in ANGLES for j in F1_COLS]


# ---- numerical check of the transition and its Jacobian ------------------------------------------
def _rot(ph: float, th: float, ps: float):
    import numpy as np

    cx, sx, cy, sy, cz, sz = np.cos(ph), np.sin(ph), np.cos(th), np.sin(th), np.cos(ps), np.sin(ps)
    return (np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]]) @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
            @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]]))


def _exp(u):
    import numpy as np

    th = float(np.linalg.norm(u))
    U = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    if th < 1e-12:
        return np.eye(3) + U
    return np.eye(3) + np.sin(th) / th * U + (1 - np.cos(th)) / th ** 2 * U @ U


def _right_jacobian(u):
    import numpy as np

    th = float(np.linalg.norm(u))
    U = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.eye(3) - (1 - np.cos(th)) / th ** 2 * U + (th - np.sin(th)) / th ** 3 * U @ U


def _angles_after(x, h):
    """Theta+ of the composed rotation, continued from Theta (psi and phi unwrapped)."""
    import numpy as np

    R = _rot(x[3], x[4], x[5]) @ _exp(np.array(x[0:3]) * h)
    ang = np.array([np.arctan2(R[2, 1], R[2, 2]), np.arctan2(-R[2, 0], np.hypot(R[2, 1], R[2, 2])),
                    np.arctan2(R[1, 0], R[0, 0])])
    return ang + 2 * np.pi * np.round((np.array(x[3:6]) - ang) / (2 * np.pi))


def _check_transition() -> None:
    """The angle rows of F2 F1 equal central differences of the composed rotation, and the
    Euler-rate rows those of W(Theta+) omega, at random states away from +-90 deg pitch."""
    import random

    import numpy as np

    D1, D2 = transition_factors()
    F = sp.lambdify([list(X), dt, list(TRIG0), list(TRIG), list(C), list(JD)], (sp.eye(9) + D2) * (sp.eye(9) + D1),
                   "numpy")
    rng = random.Random(11)
    for _ in range(20):
        x = [rng.uniform(-3, 3) for _ in range(3)] + [rng.uniform(-3, 3), rng.uniform(-1.3, 1.3),
                                                       rng.uniform(-3, 3)] + [0.0, 0.0, 0.0]
        h = rng.uniform(1e-3, 0.1)

        def full(xx):
            ang = _angles_after(xx, h)
            W = np.array(euler_rate_map(ang[0], ang[1]).evalf(), dtype=float)
            return np.concatenate([xx[0:3], ang, W @ np.array(xx[0:3])])

        ang = _angles_after(x, h)
        trig = lambda a_, b_: (np.sin(a_), np.cos(a_), np.sin(b_), np.cos(b_), 1 / np.cos(b_))  # noqa: E731
        u = np.array(x[0:3]) * h
        got = np.array(F(x, h, trig(x[3], x[4]), trig(ang[0], ang[1]), _exp(u).ravel(), (_right_jacobian(u) * h).ravel()),
                       dtype=float)
        for j in range(9):
            e = 1e-6
            xp, xm = list(x), list(x)
            xp[j] += e
            xm[j] -= e
            col = (full(xp) - full(xm)) / (2 * e)
            assert np.allclose(got[:, j], col, rtol=1e-6, atol=1e-6), (j, got[:, j], col)


def _index(i: int) -> str:
    return f"ATT_{STATE_NAMES[i]}"


TRIG_PROLOGUE = [
    "const ekf_scalar_t sph = t->sphi;",
    "const ekf_scalar_t cph = t->cphi;",
    "const ekf_scalar_t sth = t->sth;",
    "const ekf_scalar_t cth = t->cth;",
    "const ekf_scalar_t secth = t->secth;",
]
TRIG0_PROLOGUE = [
    "const ekf_scalar_t sph0 = tb->sphi;",
    "const ekf_scalar_t cph0 = tb->cphi;",
    "const ekf_scalar_t sth0 = tb->sth;",
    "const ekf_scalar_t cth0 = tb->cth;",
    "const ekf_scalar_t secth0 = tb->secth;",
]
ROT_PROLOGUE = [f"const ekf_scalar_t c{k} = rot[{k}];" for k in range(9)] + [
    f"const ekf_scalar_t j{k} = jd[{k}];" for k in range(9)]
STATE_PROLOGUE = [f"const ekf_scalar_t {s.name} = x[{_index(i)}];" for i, s in enumerate(X)]

# Typical magnitudes of the generated code's inputs, for the order of the factors of each
# product (cprinter.to_c: largest first, which keeps the fixed-point build's rounding
# relative to the result): sec(theta) up to 48 at the default gimbal limit, rates a few
# rad/s (up to gyro_range), sines and cosines below 1, steps of milliseconds, the field in uT.
SCALES = {
    **{name: 10.0 for name in ("secth", "secth0")},
    **{name: 0.7 for name in ("sph", "cph", "sth", "cth", "sph0", "cph0", "sth0", "cth0")},
    **{f"c{k}": 0.7 for k in range(9)},
    **{f"j{k}": 0.005 for k in range(9)},
    **{name: 5.0 for name in ("p", "q", "r", "phid", "thetad", "psid")},
    **{name: 1.5 for name in ("phi", "theta", "psi")},
    "dt": 0.005,
    **{name: 50.0 for name in ("mx", "my", "mz")},
}


def build() -> Dict[str, str]:
    _check_transition()
    F, G = transition_jacobians()
    # The noise Jacobian is [I; 0; W(phi+, theta+)]: only its Euler-rate block depends on
    # the state, the rest is identity and is applied as such by att_cov.
    g_block = [(i, j, G[i, j]) for i in range(6, 9) for j in range(3)]

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
    d1_entries = [(i, j, D1[i, j]) for i, j in f1_pattern()]
    d2_entries = sparse_entries(D2)
    fns.append(
        CFunction(
            scales=SCALES,
            name="att_gen_transition_factors",
            doc="F = F2 F1, F1 = I + D1, F2 = I + D2 (docs/derivation.md, \"State Jacobian\"): d1 the values\n"
            "of D1 (the angle rows: W+ Jr dt on the body rates, W+ C^T E - I on the angles, zero in\n"
            "the heading column) in the order of att_gen_f1_pattern, d2 those of D2 (the Euler-rate\n"
            "rows: W+ on the body rates, M+ on roll and pitch, -1 on the rate itself) in the order of\n"
            "att_gen_f2_pattern. x: state before the step (its body rates); tb: trigonometry of the\n"
            "angles before the step, t: of the advanced angles; rot = C = Exp([w dt]x) and\n"
            "jd = Jr(w dt) dt, row-major (att_model_rotation).",
            params="const att_trig_t *tb, const att_trig_t *t, const ekf_scalar_t x[ATT_N], const ekf_scalar_t rot[9], "
            "const ekf_scalar_t jd[9], ekf_scalar_t d1[ATT_GEN_F1_NNZ], ekf_scalar_t d2[ATT_GEN_F2_NNZ]",
            prologue=TRIG0_PROLOGUE + TRIG_PROLOGUE + STATE_PROLOGUE + ROT_PROLOGUE,
            outputs=[(f"d1[{k}]", e) for k, (_, _, e) in enumerate(d1_entries)]
            + [(f"d2[{k}]", e) for k, (_, _, e) in enumerate(d2_entries)],
        )
    )

    header_extra = '#include "att_defs.h"'
    source_extra = ""
    for name, entries, what in (("f1", d1_entries, "the angle rows"), ("f2", d2_entries, "the Euler-rate rows")):
        pat = ", ".join(f"{{{_index(i)}, {_index(j)}}}" for i, j, _ in entries)
        header_extra += (
            f"\n\n/* Number of entries of D{name[1]} = F{name[1]} - I ({what}), and their\n"
            f" * (row, column), sorted by row (att_gen_transition_factors). */\n"
            f"#define ATT_GEN_{name.upper()}_NNZ {len(entries)}\n"
            f"extern const ekf_nz_t att_gen_{name}_pattern[ATT_GEN_{name.upper()}_NNZ];"
        )
        source_extra += f"\n\nconst ekf_nz_t att_gen_{name}_pattern[ATT_GEN_{name.upper()}_NNZ] = {{{pat}}};"
    # P <- F P F^T unrolled for each factor (the reference covariance implementation,
    # att_cov_ref.c, which the tests compare the shipped ones with)
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
