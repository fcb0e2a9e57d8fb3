"""Plots of an evaluated trial (matplotlib, Agg backend: no display needed)."""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")  # files only; must precede pyplot
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .evaluate import ANGLES, TrialEval  # noqa: E402


def _shade_unscored(ax, tr: TrialEval) -> None:
    """Grey background where samples are not scored (rest before movement, no truth)."""
    t = tr.t
    off = ~tr.scored
    if not off.any():
        return
    edges = np.flatnonzero(np.diff(np.concatenate([[0], off.astype(int), [0]])))
    for a, b in zip(edges[::2], edges[1::2]):
        ax.axvspan(t[a], t[min(b, len(t) - 1)], color="0.92", lw=0, zorder=0)


def _break_wraps(a_deg: np.ndarray) -> np.ndarray:
    """NaN where an angle jumps by more than 180 deg (a wrap at +-180), so that the line is
    broken there instead of crossing the whole axis."""
    out = np.array(a_deg, dtype=np.float64, copy=True)
    jump = np.abs(np.diff(out)) > 180.0
    out[1:][jump] = np.nan
    return out


def plot_trial(tr: TrialEval, path: str, dpi: int = 110) -> str:
    """One PNG: left, roll/pitch/yaw estimate vs truth; right, their errors with the filter's
    +-3 sigma bounds; bottom, the BROAD total/heading/inclination errors. Returns path."""
    t = tr.t
    fig = plt.figure(figsize=(13, 9.5), constrained_layout=True)
    gs = fig.add_gridspec(4, 2, height_ratios=[1, 1, 1, 1.1])
    rm = tr.rmse_deg
    title = f"{tr.name}  —  {tr.estimator}"
    if tr.has_truth:
        title += (f"\nRMSE total {rm['total']:.2f}°, heading {rm['heading']:.2f}°, "
                  f"inclination {rm['inclination']:.2f}° over {tr.counts.get('scored', 0)} scored samples"
                  + (" (6D: mean heading offset removed)" if tr.six_d else ""))
    fig.suptitle(title, fontsize=11)
    deg = np.degrees
    for k, ang in enumerate(ANGLES):
        ax = fig.add_subplot(gs[k, 0])
        _shade_unscored(ax, tr)
        if tr.euler_ref is not None:
            ax.plot(t, _break_wraps(deg(tr.euler_ref[:, k])), color="k", lw=1.6, label="truth")
        ax.plot(t, _break_wraps(deg(tr.euler_est[:, k])), color="tab:blue", lw=0.9, label="estimate")
        ax.set_ylabel(f"{ang} (°)")
        ax.grid(alpha=0.3)
        if k == 0:
            ax.set_title("Euler angles (ZYX, body→ENU)", fontsize=10)
            ax.legend(loc="upper right", fontsize=8)
        if k == 2:
            ax.set_xlabel("t (s)")

        ax = fig.add_subplot(gs[k, 1])
        _shade_unscored(ax, tr)
        if tr.err_euler is not None:
            err = deg(tr.err_euler[:, k])
            ax.plot(t, err, color="tab:red", lw=0.8, label="estimate − truth")
            lim = np.nanpercentile(np.abs(err[tr.scored]), 99.5) if tr.scored.any() else 1.0
        else:
            lim = 1.0
        if tr.var_euler is not None:
            s3 = 3.0 * deg(np.sqrt(tr.var_euler[:, k]))
            ax.fill_between(t, -s3, s3, color="tab:green", alpha=0.25, lw=0, label="±3σ (filter)")
            if tr.scored.any():
                lim = max(lim, np.nanpercentile(s3[tr.scored], 95))
        # zoom on the scored part; the initial transient and unobservable yaw would flatten it
        lim = float(lim) if np.isfinite(lim) and lim > 0 else 1.0
        ax.set_ylim(-1.3 * lim, 1.3 * lim)
        ax.set_ylabel(f"{ang} error (°)")
        ax.grid(alpha=0.3)
        if k == 0:
            ax.set_title("Euler-angle error and the filter's ±3σ", fontsize=10)
            ax.legend(loc="upper right", fontsize=8)
        if k == 2:
            ax.set_xlabel("t (s)")

    ax = fig.add_subplot(gs[3, :])
    _shade_unscored(ax, tr)
    if tr.err_total is not None:
        for name, arr, color in (("total", tr.err_total, "k"), ("heading", tr.err_heading, "tab:orange"),
                                 ("inclination", tr.err_inclination, "tab:purple")):
            ax.plot(t, deg(arr), color=color, lw=0.9, label=f"{name} (RMSE {rm[name]:.2f}°)")
        ax.legend(loc="upper right", fontsize=8, ncol=3)
        if tr.scored.any():
            top = np.nanpercentile(deg(tr.err_total[tr.scored]), 99.5)
            ax.set_ylim(0, 1.3 * top if np.isfinite(top) and top > 0 else 1.0)
    else:
        ax.text(0.5, 0.5, "no ground truth in this recording", ha="center", va="center",
                transform=ax.transAxes)
    ax.set_title("BROAD errors: e = q_est · q_ref⁻¹ (grey: not scored)", fontsize=10)
    ax.set_ylabel("error (°)")
    ax.set_xlabel("t (s)")
    ax.grid(alpha=0.3)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path
