"""Reports of a benchmark result (bench.run_benchmark): the plain-text tables `attekf bench`
prints (overall, per group, per trial, coverage of the reported covariance, cost), the Markdown
tables of docs/accuracy.md and the per-group bar chart."""

from __future__ import annotations

import math
import os
from typing import Dict, List

import numpy as np

from . import consistency as C

M_KEYS = ("total", "heading", "inclination")


def _f(v, digits: int = 2) -> str:
    return "n/a" if v is None or not math.isfinite(v) else f"{v:.{digits}f}"


def _table(head: List[str], rows: List[List[str]]) -> List[str]:
    widths = [max(len(r[i]) for r in rows + [head]) for i in range(len(head))]
    fmt = lambda r: "  ".join(c.ljust(widths[0]) if i == 0 else c.rjust(widths[i])  # noqa: E731
                              for i, c in enumerate(r))
    return [fmt(head), "  ".join("-" * w for w in widths)] + [fmt(r) for r in rows]


def format_summary(result: Dict[str, object]) -> str:
    """Overall table (one row per method) and the per-group total RMSE table."""
    res = result["results"]
    meta = result["methods"]
    n = len(result["trials"])
    lines = [f"BROAD benchmark, {n} trial(s): mean over trials of the RMSE over the movement samples, deg",
             "6D rows: the mean heading offset is removed before scoring (heading drift still counts)."]
    tf = result.get("transform") or {}
    if tf.get("label", "native") != "native":
        lines.append(f"Recordings transformed: {tf['label']} (transform.py; ours gets each sample's time step, "
                     "fixed-rate methods the nominal grid with missing samples filled).")
    rows = []
    for key, r in res.items():
        o = r["overall"]
        cc = C.summary_cells(r.get("consistency", {}))
        rows.append([key, meta[key]["dim"], _f(o["total"]), _f(o["heading"]), _f(o["inclination"]),
                     cc["cov"], cc["sigma"], cc["nees"],
                     _f(r["us_per_sample"], 2 if r["us_per_sample"] < 100 else 0),
                     "ANALYSIS ONLY" if meta[key]["analysis_only"] else ""])
    lines += _table(["method", "dim", "total", "heading", "incl.", "min cov r/p/y %", "sigma r/p/y deg",
                     "NEES/dof", "us/sample", ""], rows)
    groups = [g for g in result["group_names"] if any(g in r["groups"] for r in res.values())]
    if len(groups) > 1:
        lines.append("")
        lines.append("total RMSE per group (deg; n = trials in the group):")
        n_of = {g: next(r["groups"][g]["n"] for r in res.values() if g in r["groups"]) for g in groups}
        head = ["method"] + [f"{g}({n_of[g]})" for g in groups]

        def cell(r, g):   # a dimension whose common trials differ says how many it averages
            if g not in r["groups"]:
                return ""
            n = r["groups"][g]["n"]
            return _f(r["groups"][g]["total"]) + ("" if n == n_of[g] else f" ({n})")
        rows = [[key] + [cell(r, g) for g in groups] for key, r in res.items()]
        lines += _table(head, rows)
    lines += format_excluded(result)
    return "\n".join(lines)


def format_excluded(result: Dict[str, object]) -> List[str]:
    """note lines: per dimension, the trials left out of every method's means and why."""
    out = []
    for dim in ("9D", "6D"):
        ex = [e for e in result.get("excluded", []) if e["dim"] == dim]
        if ex:
            used = len(result["trials"]) - len(ex)
            out.append(f"note: {dim} means over {used} of {len(result['trials'])} trial(s), the same for every "
                       f"{dim} method; left out: " + "; ".join(f"{e['trial']} ({e['reason']})" for e in ex))
    return out


def format_trials(result: Dict[str, object], metric: str = "total") -> str:
    res = result["results"]
    keys = list(res)
    rows = [[t] + [_f(res[k]["trials"].get(t, {}).get(metric, float("nan"))) for k in keys]
            for t in result["trials"]]
    return "\n".join([f"{metric} RMSE per trial (deg):"] + _table(["trial"] + keys, rows))


def format_consistency(result: Dict[str, object]) -> str:
    """Per trial, for the methods that report a covariance (ours): coverage r/p/y %,
    (mean sigma r/p/y deg) and NEES/dof (consistency.py)."""
    keys = [k for k, r in result["results"].items() if r.get("consistency")]
    if not keys:
        return ""
    rows = [[t] + [C.trial_cells(result["results"][k]["trials"].get(t, {})) for k in keys] for t in result["trials"]]
    return "\n".join(["coverage within 3 sigma per trial, roll/pitch/yaw % (mean sigma deg) NEES/dof:"]
                     + _table(["trial"] + keys, rows))


def format_costs(result: Dict[str, object]) -> str:
    rows = [[k, _f(r["us_per_sample"], 3), _f(r["seconds"], 1), str(r["samples"]),
             result["methods"][k]["cost_measured"]] for k, r in result["results"].items()]
    return "\n".join(["per-sample cost on this machine (" + str(result["machine"]["cpu"]) + "):"]
                     + _table(["method", "us/sample", "s", "samples", "what is timed"], rows))


def format_markdown(result: Dict[str, object]) -> str:
    """The tables of docs/accuracy.md: provenance line, overall table, total RMSE per group."""
    res = result["results"]
    meta = result["methods"]
    git = result.get("git", {})
    dirty = ""
    if git.get("uncommitted_changes"):
        dirty = " + uncommitted changes" + (f" (diff {git['diff_sha256']})" if git.get("diff_sha256") else "")
    lines = [f"Commit `{git.get('commit')}`{dirty}, {result.get('date_utc')}, "
             f"{len(result['trials'])} trials, {result['machine']['cpu']} "
             f"(`--jobs {result['machine']['jobs']}`, {result['wall_seconds']:.0f} s wall)"
             + (f", library `{result['library']}`" if result.get("library") else "") + ". Command:",
             "", "```", str(result.get("command", "attekf bench")), "```", "",
             "| method | dim | total | heading | inclination | min coverage r/p/y % | mean σ r/p/y ° | NEES/dof "
             "| µs/sample |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for key, r in res.items():
        o = r["overall"]
        tag = " (ANALYSIS ONLY)" if meta[key]["analysis_only"] else ""
        cc = C.summary_cells(r.get("consistency", {}))
        lines.append(f"| `{key}`{tag} | {meta[key]['dim']} | {_f(o['total'])} | {_f(o['heading'])} | "
                     f"{_f(o['inclination'])} | {cc['cov']} | {cc['sigma']} | {cc['nees']} | "
                     f"{_f(r['us_per_sample'], 2 if r['us_per_sample'] < 100 else 0)} |")
    groups = [g for g in result["group_names"] if any(g in r["groups"] for r in res.values())]
    if len(groups) > 1:
        n_of = {g: next(r["groups"][g]["n"] for r in res.values() if g in r["groups"]) for g in groups}
        lines += ["", "Total RMSE (deg) per group (number of trials):", "",
                  "| method | " + " | ".join(f"{g} ({n_of[g]})" for g in groups) + " |",
                  "|---|" + "---:|" * len(groups)]
        for key, r in res.items():
            lines.append(f"| `{key}` | " + " | ".join(_f(r["groups"][g]["total"]) if g in r["groups"] else ""
                                                    for g in groups) + " |")
    notes = format_excluded(result)
    return "\n".join(lines + ([""] + notes if notes else [])) + "\n"


def plot_groups(result: Dict[str, object], path: str) -> str:
    """Grouped bar chart: per group (x), one bar per method; panels total/heading/inclination."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    res = result["results"]
    groups = [g for g in result["group_names"] if any(g in r["groups"] for r in res.values())]
    keys = list(res)
    fig, axes = plt.subplots(3, 1, figsize=(max(8.0, 0.9 * len(groups) * max(1, len(keys)) / 3 + 4), 10),
                             constrained_layout=True, sharex=True)
    width = 0.8 / max(1, len(keys))
    x = np.arange(len(groups))
    cmap = plt.get_cmap("tab20" if len(keys) > 10 else "tab10")
    for ax, metric in zip(axes, M_KEYS):
        for i, k in enumerate(keys):
            vals = [res[k]["groups"].get(g, {}).get(metric, np.nan) for g in groups]
            hatch = "//" if result["methods"][k]["dim"] == "6D" else None
            ax.bar(x + (i - (len(keys) - 1) / 2) * width, vals, width, label=k, color=cmap(i % 20),
                   hatch=hatch, edgecolor="white", linewidth=0.3)
        ax.set_ylabel(f"{metric} RMSE (°)")
        ax.grid(axis="y", alpha=0.3)
    axes[0].legend(ncol=min(4, len(keys)), fontsize=8, loc="upper left")
    axes[-1].set_xticks(x)
    n_of = {g: next(r["groups"][g]["n"] for r in res.values() if g in r["groups"]) for g in groups}
    axes[-1].set_xticklabels([f"{g}\n({n_of[g]})" for g in groups], fontsize=8)
    git = result.get("git", {})
    fig.suptitle(f"BROAD, {len(result['trials'])} trials: mean RMSE per group (hatched: 6D, heading offset "
                 f"removed) — commit {git.get('commit')}{' + uncommitted changes' if git.get('uncommitted_changes') else ''}",
                 fontsize=10)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
