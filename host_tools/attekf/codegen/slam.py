"""EKF-SLAM with range-bearing landmarks (docs/models.md, "EKF-SLAM").

State ``[X, Y, psi, m1x, m1y, ..., mnx, mny]``: robot position (m) and heading (rad,
counter-clockwise from the x axis) in the world frame, then static landmark positions (m).

Motion over ``dt`` from body-frame odometry ``u = (xdot, ydot, r)`` (m/s forward, m/s
left, rad/s), heading held at its value at the start of the step (forward Euler):

    X+   = X + dt (xdot cos psi - ydot sin psi)
    Y+   = Y + dt (xdot sin psi + ydot cos psi)
    psi+ = psi + dt r

Landmarks do not move, so F is the identity outside the 3x3 pose block. The odometry
noise (variances of xdot, ydot, r) enters through G_u = df/du: Q_pose = G_u M G_u^T.

Observation of landmark j (dx = mjx - X, dy = mjy - Y):

    range   = sqrt(dx^2 + dy^2)
    bearing = atan2(dy, dx) - psi           (wrapped into [-pi, pi) by the caller)

Its Jacobian has a pose block A_j (2x3) and a landmark block B_j (2x2); in the generated
code it is one 2x5 "local" matrix over (X, Y, psi, mjx, mjy), in compressed rows.

Landmark initialisation from the first observation (range rr, bearing b), with
cb = cos(psi + b), sb = sin(psi + b):

    m = (X + rr cb, Y + rr sb),   G_x = dm/d(X, Y, psi),   G_z = dm/d(rr, b).

Trigonometry, square roots and divisions are evaluated by hand-written code (slam.c) and
passed in as symbols: c, s (of psi), cb, sb and inv_r = 1 / range.
"""

from __future__ import annotations

from typing import Dict

import sympy as sp

from .cprinter import render_files, sparse_entries
from .modelgen import CFunction, assert_same, bind, c_array, check_no_functions, csr, replace_inverse_powers

X, Y, psi = sp.symbols("X Y psi", real=True)
mx, my = sp.symbols("mx my", real=True)
xdot, ydot, yaw_rate = sp.symbols("xdot ydot yaw_rate", real=True)
var_vx, var_vy, var_r = sp.symbols("var_vx var_vy var_r", nonnegative=True)
dt = sp.Symbol("dt", positive=True)
c, s, cb, sb = sp.symbols("c s cb sb", real=True)
rr, b = sp.symbols("rr b", real=True)
r, q, inv_r, inv_q = sp.symbols("r q inv_r inv_q", positive=True)
dx, dy = sp.symbols("dx dy", real=True)

POSE = sp.Matrix([X, Y, psi])
U = sp.Matrix([xdot, ydot, yaw_rate])
LOCAL = sp.Matrix([X, Y, psi, mx, my])
POSE_NAMES = ["SLAM_X", "SLAM_Y", "SLAM_PSI"]


def motion() -> sp.Matrix:
    return sp.Matrix(
        [
            X + dt * (xdot * sp.cos(psi) - ydot * sp.sin(psi)),
            Y + dt * (xdot * sp.sin(psi) + ydot * sp.cos(psi)),
            psi + dt * yaw_rate,
        ]
    )


def observation() -> sp.Matrix:
    ex, ey = mx - X, my - Y
    return sp.Matrix([sp.sqrt(ex**2 + ey**2), sp.atan2(ey, ex) - psi])


def inverse_observation() -> sp.Matrix:
    return sp.Matrix([X + rr * sp.cos(psi + b), Y + rr * sp.sin(psi + b)])


def _trig(e: sp.Expr) -> sp.Expr:
    e = sp.sympify(e).subs({sp.cos(psi): c, sp.sin(psi): s, sp.cos(psi + b): cb, sp.sin(psi + b): sb})
    check_no_functions([e])
    return sp.expand(e)


def _range_terms(e: sp.Expr) -> sp.Expr:
    """An expression of (mx - X, my - Y) in dx, dy, inv_r = 1/r and inv_q = 1/r^2."""
    e = sp.simplify(e).subs({mx: X + dx, my: Y + dy})
    e = sp.simplify(e)
    e = e.subs(sp.sqrt(dx**2 + dy**2), r).subs(dx**2 + dy**2, q)
    e = replace_inverse_powers(sp.expand(e), r, inv_r)
    e = replace_inverse_powers(e, q, inv_q)
    return sp.expand(e)


def build() -> Dict[str, str]:
    f = motion()
    F = f.jacobian(POSE)
    d_entries = [(i, j, _trig(e)) for i, j, e in sparse_entries(F - sp.eye(3))]
    assert [(i, j) for i, j, _ in d_entries] == [(0, 2), (1, 2)], "only X, Y depend on psi"
    Gu = f.jacobian(U)
    Qp = sp.expand(Gu * sp.diag(var_vx, var_vy, var_r) * Gu.T)
    Qp = Qp.applyfunc(_trig)

    h = observation()
    H = h.jacobian(LOCAL)
    row_start, cols, values = csr(H)
    values_r = [_range_terms(v) for v in values]
    binding = {
        r: sp.sqrt(dx**2 + dy**2),
        q: dx**2 + dy**2,
        inv_r: 1 / sp.sqrt(dx**2 + dy**2),
        inv_q: 1 / (dx**2 + dy**2),
    }
    for orig, new in zip(values, values_r):
        assert_same(sp.simplify(orig).subs({mx: X + dx, my: Y + dy}), new, binding, [X, Y, psi, dx, dy])
    check_no_functions(values_r)
    assert all(v.free_symbols <= {dx, dy, inv_r} for v in values_r), "1/range^2 is inv_r^2"

    g = inverse_observation()
    Gx = g.jacobian(POSE)
    Gz = g.jacobian(sp.Matrix([rr, b]))

    pose_prologue = bind(["X", "Y", "psi"], "pose")
    fns = [
        CFunction(
            name="slam_gen_motion",
            doc="Pose after dt (s) from body-frame odometry u = (xdot m/s, ydot m/s, yaw rate rad/s);\n"
            "c, s = cos, sin of the heading at the start of the step. out must not alias pose;\n"
            "the heading is returned unwrapped.",
            params="const ekf_scalar_t pose[SLAM_POSE_N], const ekf_scalar_t u[3], ekf_scalar_t c, "
            "ekf_scalar_t s, ekf_scalar_t dt, ekf_scalar_t out[SLAM_POSE_N]",
            prologue=pose_prologue + bind(["xdot", "ydot", "yaw_rate"], "u"),
            outputs=[(f"out[{k}]", _trig(f[k])) for k in range(3)],
        ),
        CFunction(
            name="slam_gen_motion_jacobian",
            doc="Non-zero entries of D = F - I (pose block only; landmarks are static), in the\n"
            "order of slam_gen_f_pattern.",
            params="const ekf_scalar_t u[3], ekf_scalar_t c, ekf_scalar_t s, ekf_scalar_t dt, "
            "ekf_scalar_t d[SLAM_GEN_F_NNZ]",
            prologue=bind(["xdot", "ydot", "yaw_rate"], "u"),
            outputs=[(f"d[{k}]", e) for k, (_, _, e) in enumerate(d_entries)],
        ),
        CFunction(
            name="slam_gen_motion_noise",
            doc="Pose-block process noise G_u diag(var_vx, var_vy, var_r) G_u^T, row-major 3x3:\n"
            "var_vx, var_vy (m/s)^2 and var_r (rad/s)^2 are the odometry noise variances.",
            params="ekf_scalar_t c, ekf_scalar_t s, ekf_scalar_t dt, ekf_scalar_t var_vx, "
            "ekf_scalar_t var_vy, ekf_scalar_t var_r, ekf_scalar_t qp[SLAM_POSE_N * SLAM_POSE_N]",
            outputs=[(f"qp[{i * 3 + j}]", Qp[i, j]) for i in range(3) for j in range(3)],
        ),
        CFunction(
            name="slam_gen_obs_jacobian",
            doc="Non-zero entries of the observation Jacobian over (X, Y, psi, mx, my) in\n"
            "compressed-row order (slam_gen_obs_row_start, slam_gen_obs_local_col): rows range,\n"
            "bearing. dx, dy = landmark - robot (m); inv_r = 1/range (1/m).",
            params="ekf_scalar_t dx, ekf_scalar_t dy, ekf_scalar_t inv_r, ekf_scalar_t hv[SLAM_GEN_OBS_NNZ]",
            outputs=[(f"hv[{k}]", v) for k, v in enumerate(values_r)],
        ),
        CFunction(
            name="slam_gen_landmark_init",
            doc="Landmark from its first observation (range rr m, bearing b rad): m = (X + rr cb,\n"
            "Y + rr sb) with cb, sb = cos, sin(psi + b); gx = dm/d(X, Y, psi) (2x3 row-major),\n"
            "gz = dm/d(rr, b) (2x2 row-major).",
            params="const ekf_scalar_t pose[SLAM_POSE_N], ekf_scalar_t rr, ekf_scalar_t cb, ekf_scalar_t sb, "
            "ekf_scalar_t m[2], ekf_scalar_t gx[6], ekf_scalar_t gz[4]",
            prologue=pose_prologue,
            outputs=[(f"m[{k}]", _trig(g[k])) for k in range(2)]
            + [(f"gx[{i * 3 + j}]", _trig(Gx[i, j])) for i in range(2) for j in range(3)]
            + [(f"gz[{i * 2 + j}]", _trig(Gz[i, j])) for i in range(2) for j in range(2)],
        ),
    ]
    f_pattern = ", ".join(f"{{{POSE_NAMES[i]}, {POSE_NAMES[j]}}}" for i, j, _ in d_entries)
    header_extra = (
        "/* Pose entries of the state; landmark k (0-based slot) is at SLAM_POSE_N + 2k (x) and\n"
        " * SLAM_POSE_N + 2k + 1 (y). */\n"
        "enum { SLAM_X = 0, SLAM_Y = 1, SLAM_PSI = 2, SLAM_POSE_N = 3 };\n\n"
        "/* Local variables of one observation's Jacobian: the pose, then the landmark. */\n"
        "enum { SLAM_L_X = 0, SLAM_L_Y = 1, SLAM_L_PSI = 2, SLAM_L_MX = 3, SLAM_L_MY = 4, SLAM_L_N = 5 };\n\n"
        "/* Observation components. */\n"
        "enum { SLAM_RANGE = 0, SLAM_BEARING = 1, SLAM_M = 2 };\n\n"
        f"#define SLAM_GEN_F_NNZ {len(d_entries)}\n"
        f"#define SLAM_GEN_OBS_NNZ {len(values_r)}\n\n"
        "/* (row, column) of each entry of D = F - I, sorted by row. */\n"
        "extern const ekf_nz_t slam_gen_f_pattern[SLAM_GEN_F_NNZ];\n\n"
        "/* Observation Jacobian in compressed rows over the local variables SLAM_L_*. */\n"
        "extern const uint8_t slam_gen_obs_row_start[SLAM_M + 1];\n"
        "extern const uint8_t slam_gen_obs_local_col[SLAM_GEN_OBS_NNZ];"
    )
    local_names = ["SLAM_L_X", "SLAM_L_Y", "SLAM_L_PSI", "SLAM_L_MX", "SLAM_L_MY"]
    source_extra = "\n".join(
        [
            c_array("ekf_nz_t", "slam_gen_f_pattern", "SLAM_GEN_F_NNZ", [f_pattern]),
            c_array("uint8_t", "slam_gen_obs_row_start", "SLAM_M + 1", [f"{v}u" for v in row_start]),
            c_array("uint8_t", "slam_gen_obs_local_col", "SLAM_GEN_OBS_NNZ", [local_names[j] for j in cols]),
        ]
    )
    return render_files(
        stem="slam_gen",
        title="EKF-SLAM: odometry motion, range-bearing observation and landmark initialisation",
        script="host_tools/attekf/codegen/slam.py",
        includes=["ekf.h"],
        header_extra=header_extra,
        source_extra=source_extra,
        functions=fns,
    )
