#!/usr/bin/env python3
"""Polynomial coefficients of firmware/ekf/ekf_math.c (float sin, cos, atan).

Each kernel is fitted for minimax *relative* error on its reduced interval with Lawson's
iteratively reweighted least squares on a dense grid (double precision, numpy), in the form
the C code evaluates (Horner in z = r^2; the leading terms r, 1 - z/2 and t kept exact):

    sin(r) ~ r + r z (S1 + z (S2 + z S3))            |r| <= pi/4
    cos(r) ~ 1 - z/2 + z^2 (C1 + z (C2 + z C3))      |r| <= pi/4
    atan(t) ~ t + t z (A1 + z (A2 + z (A3 + z A4)))  |t| <= tan(pi/8)

and printed rounded to float (9 significant digits), with the fit's relative error. The
error of the float evaluation (what the header states) is measured by tests/c/test_ekf_math.c.

    scripts/fit_ekf_math.py
"""
import numpy as np


def lawson(x, target, basis, rel, iters=400):
    """Minimax fit of target ~ sum c_k basis_k on the grid x; relative weights 1/rel."""
    A = np.stack([b(x) for b in basis], axis=1) / rel[:, None]
    y = target / rel
    w = np.full(len(x), 1.0 / len(x))
    for _ in range(iters):
        sw = np.sqrt(w)
        c, *_ = np.linalg.lstsq(A * sw[:, None], y * sw, rcond=None)
        e = np.abs(A @ c - y)
        w = w * e
        w /= w.sum()
    return c, np.max(np.abs(A @ c - y))


def main():
    r = np.linspace(1e-4, np.pi / 4, 20000)
    z = r * r
    # sin(r) - r = r z (S1 + S2 z + S3 z^2)
    s, es = lawson(r, np.sin(r) - r, [lambda t: t**3, lambda t: t**5, lambda t: t**7], np.sin(r))
    # cos(r) - (1 - z/2) = z^2 (C1 + C2 z + C3 z^2)
    c, ec = lawson(r, np.cos(r) - (1 - z / 2), [lambda t: t**4, lambda t: t**6, lambda t: t**8], np.cos(r))
    t = np.linspace(1e-4, np.tan(np.pi / 8), 20000)
    a, ea = lawson(t, np.arctan(t) - t, [lambda u: u**3, lambda u: u**5, lambda u: u**7, lambda u: u**9],
                   np.arctan(t))
    for name, coef, err in (("S", s, es), ("C", c, ec), ("A", a, ea)):
        print(f"{name}: " + ", ".join(f"{np.float32(v):.9e}" for v in coef) + f"   (fit rel. error {err:.2e})")


if __name__ == "__main__":
    main()
