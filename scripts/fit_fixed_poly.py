#!/usr/bin/env python3
"""Polynomial coefficients of firmware/ekf/ekf_fixed.c (fixed-point sin, cos, atan).

Each kernel is fitted for minimax *absolute* error (what ekf_fixed.h states) on its reduced
interval, with a small margin for the reduction's rounding, by Lawson's iteratively
reweighted least squares on Chebyshev nodes, in the form the C code evaluates (Horner in
u = r^2, Q0.31; the linear term kept exact):

    sin(r) ~ r + r u (S0 + u (S1 + u (S2 + u S3)))                 |r| <= pi/4 + 2e-3
    cos(r) ~ 1 + u (C0 + u (C1 + u (C2 + u (C3 + u C4))))          |r| <= pi/4 + 2e-3
    atan(t) ~ t + t u (A0 + u (A1 + ... + u A5))                   |t| <= tan(pi/8) + 1e-4

The target functions are evaluated in 40-digit arithmetic (mpmath, a dependency of sympy),
so that the cancellation in (sin(r) / r - 1) / u does not limit the fit. Prints the
coefficients (Horner order, highest power first, as the C tables) and the fit's error; the
error of the 32-bit evaluation is measured by tests/c/test_fixed.c.

    scripts/fit_fixed_poly.py
"""
import mpmath as mp
import numpy as np

mp.mp.dps = 40


def lawson(u, target, scale, degree, iters=300):
    """Minimax fit of target(u) ~ sum_k c_k u^k, error weighted by scale(u)."""
    A = np.vstack([u**k for k in range(degree + 1)]).T
    w = np.full(len(u), 1.0 / len(u))
    best = None
    for _ in range(iters):
        sw = np.sqrt(w) * scale
        c, *_ = np.linalg.lstsq(A * sw[:, None], target * sw, rcond=None)
        e = np.abs(A @ c - target) * scale
        if best is None or e.max() < best[1]:
            best = (c, e.max())
        w = w * e
        w /= w.sum()
    return best


def fit(name, g, umax, scale, degree, n=3000):
    k = np.arange(n)
    u = (np.cos((2 * k + 1) / (2 * n) * np.pi) + 1) / 2 * umax
    target = np.array([float(g(mp.mpf(float(x)))) for x in u])
    c, err = lawson(u, target, scale(u), degree)
    print(f"{name}: degree {degree} in u, max abs error of the fit {err:.3g}")
    print("    " + ", ".join(f"Q31({float(v)!r})" for v in reversed(list(c))))


def main():
    r_max = float(mp.pi / 4) + 2e-3
    t_max = float(mp.tan(mp.pi / 8)) + 1e-4
    # sin(r) = r + r u S(u): S(u) = (sin(r) / r - 1) / u, its error scaled by r u = u^1.5
    fit("sin", lambda u: (mp.sin(mp.sqrt(u)) / mp.sqrt(u) - 1) / u if u else mp.mpf(-1) / 6, r_max**2,
        lambda u: u**1.5, 3)
    # cos(r) = 1 + u C(u): C(u) = (cos(r) - 1) / u, error scaled by u
    fit("cos", lambda u: (mp.cos(mp.sqrt(u)) - 1) / u if u else mp.mpf(-1) / 2, r_max**2, lambda u: u, 4)
    # atan(t) = t + t u A(u): A(u) = (atan(t) / t - 1) / u, error scaled by u^1.5
    fit("atan", lambda u: (mp.atan(mp.sqrt(u)) / mp.sqrt(u) - 1) / u if u else mp.mpf(-1) / 3, t_max**2,
        lambda u: u**1.5, 5)


if __name__ == "__main__":
    main()
