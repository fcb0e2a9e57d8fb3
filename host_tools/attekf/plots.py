"""Plots of an evaluated trial (matplotlib, Agg backend: no display needed).

One figure, four rows by two columns, every panel on the same time axis:

* left, roll / pitch / yaw: the estimate (wide, light) under the truth (thin, black), so the
  truth stays visible where the two agree. Angles are unwrapped (no jump at +-180 deg) and
  the estimate is drawn on the truth's branch, so the two are comparable everywhere; in 6D the
  removed heading offset is taken out of the estimate's yaw as it is out of the scores;
* right, the Euler-angle errors with the filter's +-3 sigma band, zoomed on the scored part;
* bottom left, the BROAD total / heading / inclination errors;
* bottom right, which ATT_FLAG_* bits the filter raised when.

Errors beyond a panel's range are drawn as triangles on its edge and counted in the panel.
Grey background: samples not scored. Coloured bands: disturbance episodes the recording
declares (attekf sim's metadata).
"""

from __future__ import annotations

from typing import Dict, List, Optional, Tuple

import matplotlib

matplotlib.use("Agg")  # files only; must precede pyplot
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .evaluate import ANGLES, TrialEval  # noqa: E402

EPISODE_STYLE = {"linear_acceleration": ("tab:orange", "linear acceleration"),
                 "magnetic_disturbance": ("tab:purple", "magnetic disturbance")}
ZOOM = 1.3   # error panels: range = ZOOM x the 99.5th percentile over the scored samples


def flag_names() -> Dict[str, int]:
    """ATT_FLAG_* bits by name (firmware/att/att.h)."""
    from .native import ATT_FLAGS
    names = dict(ATT_FLAGS)
    # bits of att.h the binding's table does not list
    names.setdefault("COV_REPAIRED", 1 << 12)
    names.setdefault("AT_REST", 1 << 13)
    return names


# ---------------------------------------------------------------------------------------------
# Angles for display
# ---------------------------------------------------------------------------------------------
def unwrap_deg(a_deg: np.ndarray) -> np.ndarray:
    """Unwraps an angle series (deg) over its finite samples; NaN stays NaN."""
    out = np.array(a_deg, dtype=np.float64, copy=True)
    ok = np.isfinite(out)
    if ok.sum() > 1:
        out[ok] = np.degrees(np.unwrap(np.radians(out[ok])))
    return out


def on_branch(est_deg: np.ndarray, ref_unwrapped_deg: np.ndarray) -> np.ndarray:
    """The estimate unwrapped and moved by whole turns onto the truth's branch: where truth
    exists est + 360 k is within 180 deg of it; elsewhere the last (or next) shift holds."""
    est = unwrap_deg(est_deg)
    shift = np.full(est.shape, np.nan)
    both = np.isfinite(est) & np.isfinite(ref_unwrapped_deg)
    shift[both] = 360.0 * np.round((ref_unwrapped_deg[both] - est[both]) / 360.0)
    if not both.any():
        return est
    idx = np.where(np.isfinite(shift), np.arange(shift.size), 0)
    np.maximum.accumulate(idx, out=idx)
    filled = shift[idx]
    first = int(np.argmax(both))
    filled[:first] = shift[first]
    return est + filled


def display_angles(tr: TrialEval) -> Tuple[Optional[np.ndarray], np.ndarray]:
    """(truth, estimate) in degrees as drawn: unwrapped, estimate on the truth's branch, in 6D
    the removed heading offset taken out of the estimate's yaw."""
    est = np.degrees(tr.euler_est)
    if tr.six_d and tr.heading_offset_deg:
        est = est.copy()
        est[:, 2] -= tr.heading_offset_deg   # a turn about earth z changes only ZYX yaw
    if tr.euler_ref is None:
        return None, np.stack([unwrap_deg(est[:, k]) for k in range(3)], axis=1)
    ref = np.stack([unwrap_deg(np.degrees(tr.euler_ref[:, k])) for k in range(3)], axis=1)
    return ref, np.stack([on_branch(est[:, k], ref[:, k]) for k in range(3)], axis=1)


# ---------------------------------------------------------------------------------------------
# Panel helpers
# ---------------------------------------------------------------------------------------------
def _spans(mask: np.ndarray) -> List[Tuple[int, int]]:
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return list(zip(edges[::2], edges[1::2]))


def _background(ax, tr: TrialEval) -> None:
    """Grey where samples are not scored, coloured bands over disturbance episodes."""
    t = tr.t
    for a, b in _spans(~tr.scored):
        ax.axvspan(t[a], t[min(b, len(t) - 1)], color="0.92", lw=0, zorder=0)
    for kind, start, stop in tr.episodes:
        color, _label = EPISODE_STYLE.get(kind, ("tab:brown", kind.replace("_", " ")))
        ax.axvspan(start, stop, color=color, alpha=0.13, lw=0, zorder=0.5)


def limit(values: np.ndarray, scored: np.ndarray, floor: float = 0.0) -> float:
    """Half-range of an error panel: ZOOM x the 99.5th percentile of |values| where scored."""
    sel = np.abs(values[scored & np.isfinite(values)])
    lim = float(np.percentile(sel, 99.5)) if sel.size else 1.0
    lim = max(lim, floor)
    return ZOOM * lim if np.isfinite(lim) and lim > 0 else 1.0


def mark_beyond(ax, t: np.ndarray, y: np.ndarray, lo: float, hi: float, color: str) -> int:
    """Triangles on the panel's edge for the samples of y outside [lo, hi]; their count."""
    above = np.isfinite(y) & (y > hi)
    below = np.isfinite(y) & (y < lo)
    pad = 0.03 * (hi - lo)
    for sel, yy, marker in ((above, hi - pad, "^"), (below, lo + pad, "v")):
        if sel.any():
            ts = t[sel]
            if ts.size > 300:   # at most one marker per 1/300 of the time axis: enough to see
                width = (t[-1] - t[0]) / 300 or 1.0
                ts = ts[np.unique(np.floor((ts - t[0]) / width), return_index=True)[1]]
            ax.plot(ts, np.full(ts.shape, yy), linestyle="none", marker=marker, ms=4, color=color,
                    clip_on=False, zorder=4)
    n = int(above.sum() + below.sum())
    return n


def _note_beyond(ax, n: int, total: int, lim_text: str) -> None:
    if n:
        ax.text(0.01, 0.97, f"▲▼ {n} of {total} samples beyond {lim_text}", transform=ax.transAxes,
                ha="left", va="top", fontsize=7, color="0.2",
                bbox=dict(boxstyle="round,pad=0.2", fc="white", ec="0.7", alpha=0.85), zorder=5)


def _legend_extra(tr: TrialEval):
    from matplotlib.patches import Patch
    handles = [Patch(color="0.85", label="not scored")]
    for kind in sorted({k for k, _a, _b in tr.episodes}):
        color, label = EPISODE_STYLE.get(kind, ("tab:brown", kind.replace("_", " ")))
        handles.append(Patch(color=color, alpha=0.3, label=label))
    return handles


# ---------------------------------------------------------------------------------------------
# The figure
# ---------------------------------------------------------------------------------------------
PLOT_STEPS = 5  # progress steps of plot_trial: the four rows of panels, then the PNG


def plot_trial(tr: TrialEval, path: str, dpi: int = 110, progress=None) -> str:
    """Writes the trial's figure (module docstring) as a PNG to path (atomically); returns path.
    progress(1) is called PLOT_STEPS times along the way."""
    from .outputs import atomic_path
    fig = trial_figure(tr, progress)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=dpi, format="png")
        if progress is not None:
            progress(1)
    finally:
        plt.close(fig)
    return path


def trial_figure(tr: TrialEval, progress=None):
    """The trial's figure (module docstring); the caller closes it. progress(1) after each of
    the four rows of panels."""
    t = tr.t
    fig, axes = plt.subplots(4, 2, figsize=(14, 10.5), sharex=True, constrained_layout=True,
                             gridspec_kw={"height_ratios": [1, 1, 1, 1.1]})
    rm = tr.rmse_deg
    title = f"{tr.name}  —  {tr.estimator}"
    if tr.has_truth:
        title += (f"\nRMSE total {rm['total']:.2f}°, heading {rm['heading']:.2f}°, "
                  f"inclination {rm['inclination']:.2f}° over {tr.counts.get('scored', 0)} scored samples"
                  + (f" (6D: mean heading offset {tr.heading_offset_deg:.1f}° removed)" if tr.six_d else ""))
    fig.suptitle(title, fontsize=11)
    ref, est = display_angles(tr)
    n_scored = int(tr.scored.sum())
    for k, ang in enumerate(ANGLES):
        ax = axes[k, 0]
        _background(ax, tr)
        ax.plot(t, est[:, k], color="tab:cyan", lw=2.2, alpha=0.8, label="estimate", zorder=2)
        if ref is not None:
            ax.plot(t, ref[:, k], color="k", lw=0.7, label="truth", zorder=3)
        ax.set_ylabel(f"{ang} (°{', unwrapped' if ang != 'pitch' else ''})")
        ax.grid(alpha=0.3)
        if k == 0:
            ax.set_title("Euler angles (ZYX, body→ENU)", fontsize=10)
            lines = ax.get_legend_handles_labels()[0]
            ax.legend(handles=lines + _legend_extra(tr), loc="upper right", fontsize=7, ncol=2)

        ax = axes[k, 1]
        _background(ax, tr)
        lim = 1.0
        if tr.err_euler is not None:
            err = np.degrees(tr.err_euler[:, k])
            s3 = 3.0 * np.degrees(np.sqrt(tr.var_euler[:, k])) if tr.var_euler is not None else None
            # the band widens the range to show itself, except for the 6D yaw, whose band (an
            # unobservable heading) would flatten the error to a line
            floor = float(np.nanpercentile(s3[tr.scored], 95)) \
                if s3 is not None and n_scored and not (tr.six_d and ang == "yaw") else 0.0
            lim = limit(err, tr.scored, floor if np.isfinite(floor) else 0.0)
            if s3 is not None:
                ax.fill_between(t, -s3, s3, color="tab:green", alpha=0.25, lw=0, label="±3σ (filter)")
            ax.plot(t, err, color="tab:red", lw=0.6, label="estimate − truth", zorder=2)
            n = mark_beyond(ax, t, err, -lim, lim, "tab:red")
            _note_beyond(ax, n, int(np.isfinite(err).sum()), f"±{lim:.3g}°")
        elif tr.var_euler is not None:   # no truth: the filter's own band, and say so
            s3 = 3.0 * np.degrees(np.sqrt(tr.var_euler[:, k]))
            finite = s3[np.isfinite(s3)]
            lim = max(1.2 * float(np.percentile(finite, 95)), 1e-3) if finite.size else 1.0
            ax.fill_between(t, -s3, s3, color="tab:green", alpha=0.25, lw=0, label="±3σ (filter)")
            ax.text(0.01, 0.96, "no ground truth: no error, the filter's ±3σ only", transform=ax.transAxes,
                    fontsize=7, va="top")
        ax.set_ylim(-lim, lim)
        ax.set_ylabel(f"{ang} error (°)")
        ax.grid(alpha=0.3)
        if k == 0:
            ax.set_title("Euler-angle error and the filter's ±3σ", fontsize=10)
            if ax.get_legend_handles_labels()[0]:
                ax.legend(loc="upper right", fontsize=7)
        if progress is not None:
            progress(1)

    ax = axes[3, 0]
    _background(ax, tr)
    if tr.err_total is not None:
        top = limit(np.degrees(tr.err_total), tr.scored)
        beyond = 0
        # total >= heading, inclination: drawn last and thin, it stays visible on top
        for name, arr, color, lw in (("inclination", tr.err_inclination, "tab:purple", 1.0),
                                     ("heading", tr.err_heading, "tab:orange", 1.0),
                                     ("total", tr.err_total, "k", 0.6)):
            ax.plot(t, np.degrees(arr), color=color, lw=lw, alpha=0.9 if name == "total" else 0.7,
                    label=f"{name} (RMSE {rm[name]:.2f}°)")
            beyond = max(beyond, mark_beyond(ax, t, np.degrees(arr), -1.0, top, color))
        ax.set_ylim(0, top)
        _note_beyond(ax, beyond, int(np.isfinite(tr.err_total).sum()), f"{top:.3g}°")
        ax.legend(loc="upper right", fontsize=7, ncol=3)
    else:
        ax.text(0.5, 0.5, "no ground truth in this recording", ha="center", va="center",
                transform=ax.transAxes)
    ax.set_title("BROAD errors: e = q_est · q_ref⁻¹", fontsize=10)
    ax.set_ylabel("error (°)")
    ax.set_xlabel("t (s)")
    ax.grid(alpha=0.3)

    _plot_flags(axes[3, 1], tr)
    axes[3, 1].set_xlabel("t (s)")
    if len(t):
        axes[0, 0].set_xlim(t[0], t[-1])
    if progress is not None:
        progress(1)
    return fig


def _plot_flags(ax, tr: TrialEval) -> None:
    """One row per ATT_FLAG_* bit that was ever set (ALIGNED excepted), a bar where set."""
    _background(ax, tr)
    ax.set_title("filter flags (ATT_FLAG_*)", fontsize=10)
    if tr.flags is None:
        ax.text(0.5, 0.5, "no flags in this output", ha="center", va="center", transform=ax.transAxes)
        ax.set_yticks([])
        return
    rows = [(name, bit) for name, bit in flag_names().items()
            if name != "ALIGNED" and np.any(tr.flags & bit)]
    if not rows:
        ax.text(0.5, 0.5, "no flag raised", ha="center", va="center", transform=ax.transAxes)
        ax.set_yticks([])
        return
    for i, (name, bit) in enumerate(rows):
        on = (tr.flags & bit) != 0
        spans = [(tr.t[a], tr.t[min(b, len(tr.t) - 1)] - tr.t[a]) for a, b in _spans(on)]
        # one neutral colour: the episode bands' colours keep their meaning
        ax.broken_barh(spans, (i - 0.35, 0.7), color="0.3", lw=0)
    ax.set_yticks(range(len(rows)))
    def share(bit: int) -> str:
        pct = 100.0 * np.mean((tr.flags & bit) != 0)
        return f"{pct:.0f} %" if pct >= 1 else "<1 %"
    ax.set_yticklabels([f"{n.lower()} ({share(b)})" for n, b in rows], fontsize=7)
    ax.set_ylim(-0.6, len(rows) - 0.4)
    ax.grid(axis="x", alpha=0.3)
