"""Constant-acceleration motion model, MATLAB ``constacc`` / ``constaccjac`` semantics
(docs/models.md, "Constant acceleration").

State per spatial dimension ``[x; vx; ax]`` (m, m/s, m/s^2); 2-D and 3-D states stack one
block per axis: ``[x; vx; ax; y; vy; ay; z; vz; az]``. One noise input ``w`` per axis: the
acceleration increment (m/s^2) applied at the start of the step and held over it
(piecewise-constant acceleration with random increments, the discrete Wiener-process
acceleration model):

    x+  = x + T vx + T^2/2 (ax + w)
    vx+ = vx + T (ax + w)
    ax+ = ax + w

so the Jacobians are ``F = df/dx = [1 T T^2/2; 0 1 T; 0 0 1]`` and ``G = df/dw =
[T^2/2; T; 1]`` per block, and ``Q = G Var(w) G^T``. Everything below is per block; the
hand-written firmware/models/ca.c stacks the blocks.
"""

from __future__ import annotations

from typing import Dict

import sympy as sp

from .cprinter import render_files, sparse_entries
from .modelgen import CFunction, c_array

x, vx, ax = sp.symbols("x vx ax", real=True)
w = sp.Symbol("w", real=True)
dt = sp.Symbol("dt", positive=True)
BLOCK = sp.Matrix([x, vx, ax])


def transition() -> sp.Matrix:
    a = ax + w
    return sp.Matrix([x + dt * vx + dt**2 / 2 * a, vx + dt * a, a])


def build() -> Dict[str, str]:
    f = transition()
    F = f.jacobian(BLOCK).subs(w, 0)
    G = f.jacobian(sp.Matrix([w]))
    assert not (F.free_symbols & {x, vx, ax, w}), "the CA Jacobian is state-independent"
    d_entries = sparse_entries(F - sp.eye(3))
    assert [(i, j) for i, j, _ in d_entries] == [(0, 1), (0, 2), (1, 2)]

    fns = [
        CFunction(
            name="ca_gen_block_transition",
            doc="One axis of the transition (MATLAB constacc): s = (position m, velocity m/s,\n"
            "acceleration m/s^2) -> out after dt (s), with acceleration increment w (m/s^2).\n"
            "out must not alias s.",
            params="const ekf_scalar_t s[CA_BLOCK], ekf_scalar_t w, ekf_scalar_t dt, ekf_scalar_t out[CA_BLOCK]",
            prologue=[
                "const ekf_scalar_t x = s[0];",
                "const ekf_scalar_t vx = s[1];",
                "const ekf_scalar_t ax = s[2];",
            ],
            outputs=[(f"out[{k}]", sp.expand(f[k])) for k in range(3)],
        ),
        CFunction(
            name="ca_gen_block_jacobian",
            doc="Non-zero entries of one block of D = F - I (F = df/dx, MATLAB constaccjac's\n"
            "Jx), in the order of ca_gen_block_pattern. dt: step (s).",
            params="ekf_scalar_t dt, ekf_scalar_t d[CA_GEN_BLOCK_NNZ]",
            outputs=[(f"d[{k}]", e) for k, (_, _, e) in enumerate(d_entries)],
        ),
        CFunction(
            name="ca_gen_block_noise",
            doc="One block of G = df/dw (MATLAB constaccjac's Jw): the response of (position,\n"
            "velocity, acceleration) to the acceleration increment w. dt: step (s).",
            params="ekf_scalar_t dt, ekf_scalar_t g[CA_BLOCK]",
            outputs=[(f"g[{k}]", G[k, 0]) for k in range(3)],
        ),
    ]
    pattern = ", ".join(f"{{{i}, {j}}}" for i, j, _ in d_entries)
    header_extra = (
        "/* State entries per spatial axis: position (m), velocity (m/s), acceleration (m/s^2). */\n"
        "#define CA_BLOCK 3\n\n"
        "/* Number of structurally non-zero entries of one block of D = F - I. */\n"
        f"#define CA_GEN_BLOCK_NNZ {len(d_entries)}\n\n"
        "/* (row, column) inside one block of each entry of D, sorted by row. */\n"
        "extern const ekf_nz_t ca_gen_block_pattern[CA_GEN_BLOCK_NNZ];"
    )
    source_extra = c_array("ekf_nz_t", "ca_gen_block_pattern", "CA_GEN_BLOCK_NNZ", [pattern])
    return render_files(
        stem="ca_gen",
        title="constant-acceleration motion model: transition and Jacobians per axis",
        script="host_tools/attekf/codegen/constacc.py",
        includes=["ekf.h"],
        header_extra=header_extra,
        source_extra=source_extra,
        functions=fns,
    )
