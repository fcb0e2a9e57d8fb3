"""Radar (polar) and lidar (Cartesian) measurements of a 2-D constant-velocity target
(docs/models.md, "Radar and lidar").

State ``[px, py, vx, vy]`` (m, m, m/s, m/s), sensor at the origin.

Motion: constant velocity with a random acceleration ``a = (ax, ay)`` (m/s^2) held over each
step (MATLAB ``constvel``'s noise convention):

    p+ = p + T v + T^2/2 a,     v+ = v + T a,     Q = G diag(var_ax, var_ay) G^T.

Radar: ``h(x) = (rho, phi, rhodot)`` with ``rho = sqrt(px^2 + py^2)``, ``phi =
atan2(py, px)``, ``rhodot = (px vx + py vy) / rho``. The square root and atan2 are evaluated
by hand-written code (radar.c); the generated functions take ``inv_rho = 1 / rho``.

Lidar: ``h(x) = (px, py)``, linear: its rows of H are constants and need no generation.
"""

from __future__ import annotations

from typing import Dict

import sympy as sp

from .cprinter import render_files, sparse_entries
from .modelgen import CFunction, assert_same, bind, c_array, check_no_functions, csr, replace_inverse_powers

STATE_NAMES = ["PX", "PY", "VX", "VY"]
px, py, vx, vy = sp.symbols("px py vx vy", real=True)
X = sp.Matrix([px, py, vx, vy])
ax, ay = sp.symbols("ax ay", real=True)
var_ax, var_ay = sp.symbols("var_ax var_ay", nonnegative=True)
dt = sp.Symbol("dt", positive=True)
rho, inv_rho = sp.symbols("rho inv_rho", positive=True)


def transition() -> sp.Matrix:
    return sp.Matrix([px + dt * vx + dt**2 / 2 * ax, py + dt * vy + dt**2 / 2 * ay, vx + dt * ax, vy + dt * ay])


def measurement() -> sp.Matrix:
    r = sp.sqrt(px**2 + py**2)
    return sp.Matrix([r, sp.atan2(py, px), (px * vx + py * vy) / r])


def _in_inv_rho(expr: sp.Expr) -> sp.Expr:
    """Rewrite an expression of px, py in terms of rho = sqrt(px^2 + py^2) and inv_rho."""
    e = sp.simplify(expr)
    e = e.subs(sp.sqrt(px**2 + py**2), rho).subs(px**2 + py**2, rho**2)
    e = replace_inverse_powers(sp.expand(e), rho, inv_rho)
    return sp.expand(e)


def _index(i: int) -> str:
    return f"RADAR_{STATE_NAMES[i]}"


def build() -> Dict[str, str]:
    f = transition()
    F = f.jacobian(X).subs({ax: 0, ay: 0})
    d_entries = sparse_entries(F - sp.eye(4))
    G = f.jacobian(sp.Matrix([ax, ay]))
    Q = sp.expand(G * sp.diag(var_ax, var_ay) * G.T)

    h = measurement()
    H = h.jacobian(X)
    row_start, cols, values = csr(H)
    values = [_in_inv_rho(v) for v in values]
    binding = {rho: sp.sqrt(px**2 + py**2), inv_rho: 1 / sp.sqrt(px**2 + py**2)}
    for orig, new in zip(sparse_entries(H), values):
        assert_same(orig[2], new, binding, [px, py, vx, vy])
    check_no_functions(values)
    rhodot = _in_inv_rho(h[2])
    assert_same(h[2], rhodot, binding, [px, py, vx, vy])

    state_prologue = bind(["px", "py", "vx", "vy"], "x")
    fns = [
        CFunction(
            name="radar_gen_cv_jacobian",
            doc="Non-zero entries of D = F - I of the constant-velocity transition, in the order\n"
            "of radar_gen_f_pattern. dt: step (s).",
            params="ekf_scalar_t dt, ekf_scalar_t d[RADAR_GEN_F_NNZ]",
            outputs=[(f"d[{k}]", e) for k, (_, _, e) in enumerate(d_entries)],
        ),
        CFunction(
            name="radar_gen_cv_noise",
            doc="Process noise Q = G diag(var_ax, var_ay) G^T (row-major 4x4) of one step dt (s):\n"
            "var_ax, var_ay are the variances of the acceleration held over the step, (m/s^2)^2.",
            params="ekf_scalar_t dt, ekf_scalar_t var_ax, ekf_scalar_t var_ay, ekf_scalar_t q[RADAR_N * RADAR_N]",
            outputs=[(f"q[{i * 4 + j}]", Q[i, j]) for i in range(4) for j in range(4)],
        ),
        CFunction(
            name="radar_gen_range_rate",
            doc="Range rate rhodot = (px vx + py vy) / rho (m/s); inv_rho = 1 / rho (1/m).",
            params="const ekf_scalar_t x[RADAR_N], ekf_scalar_t inv_rho, ekf_scalar_t *rhodot",
            prologue=state_prologue,
            outputs=[("*rhodot", rhodot)],
        ),
        CFunction(
            name="radar_gen_h_jacobian",
            doc="Non-zero entries of the radar Jacobian H = dh/dx (rows rho, phi, rhodot) in\n"
            "compressed-row order (radar_gen_h_row_start, radar_gen_h_col).\n"
            "inv_rho = 1 / sqrt(px^2 + py^2) (1/m), finite: the caller checks the range.",
            params="const ekf_scalar_t x[RADAR_N], ekf_scalar_t inv_rho, ekf_scalar_t hv[RADAR_GEN_H_NNZ]",
            prologue=state_prologue,
            outputs=[(f"hv[{k}]", v) for k, v in enumerate(values)],
        ),
    ]
    names = ",\n    ".join(f"{_index(i)} = {i}" for i in range(4))
    f_pattern = ", ".join(f"{{{_index(i)}, {_index(j)}}}" for i, j, _ in d_entries)
    header_extra = (
        "/* State layout: position (m) and velocity (m/s) in the sensor's Cartesian frame. */\n"
        f"enum {{\n    {names},\n    RADAR_N = 4\n}};\n\n"
        "/* Radar measurement components. */\n"
        "enum { RADAR_RHO = 0, RADAR_PHI = 1, RADAR_RHODOT = 2, RADAR_M = 3 };\n\n"
        "/* Number of structurally non-zero entries of D = F - I and of H. */\n"
        f"#define RADAR_GEN_F_NNZ {len(d_entries)}\n"
        f"#define RADAR_GEN_H_NNZ {len(values)}\n\n"
        "/* (row, column) of each entry of D, sorted by row: the pattern for ekf_cov_propagate. */\n"
        "extern const ekf_nz_t radar_gen_f_pattern[RADAR_GEN_F_NNZ];\n\n"
        "/* H in compressed rows: the entries of row m are k = row_start[m] .. row_start[m+1]-1,\n"
        " * in column col[k]. */\n"
        "extern const uint8_t radar_gen_h_row_start[RADAR_M + 1];\n"
        "extern const uint8_t radar_gen_h_col[RADAR_GEN_H_NNZ];"
    )
    source_extra = "\n".join(
        [
            c_array("ekf_nz_t", "radar_gen_f_pattern", "RADAR_GEN_F_NNZ", [f_pattern]),
            c_array("uint8_t", "radar_gen_h_row_start", "RADAR_M + 1", [f"{v}u" for v in row_start]),
            c_array("uint8_t", "radar_gen_h_col", "RADAR_GEN_H_NNZ", [_index(j) for j in cols]),
        ]
    )
    return render_files(
        stem="radar_gen",
        title="radar/lidar target model: constant-velocity motion and polar measurement Jacobian",
        script="host_tools/attekf/codegen/radar.py",
        includes=["ekf.h"],
        header_extra=header_extra,
        source_extra=source_extra,
        functions=fns,
    )
