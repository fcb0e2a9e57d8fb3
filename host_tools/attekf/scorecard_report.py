"""The rows of the robustness scorecard from the task results of scorecard.run: one row per
target of issue 22, ours beside VQF online (and VQF offline where the BROAD benchmark has it),
the target and pass/miss; the text table and the JSON form (docs/accuracy.md, "How the
robustness targets are measured")."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Dict, List, Optional, Sequence

import numpy as np

from . import robustness as R
from . import scorecard as SC
from .bench_report import _table

DIMS = (("9D", "9d"), ("6D", "6d"))
BROAD_PART = "BROAD at other rates: mean total RMSE over the trials (deg)"
GLITCH_HZ = f"{SC.GLITCH_RATE_HZ:g} Hz"


@dataclass
class Row:
    part: str
    measure: str
    ours: str
    online: str
    offline: str = ""
    target: str = ""
    passed: Optional[bool] = None           # None: not measurable in this run
    values: Dict[str, object] = field(default_factory=dict)


def _f(v, digits: int = 2, signed: bool = False) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "n/a"
    if math.isinf(v):
        return "inf"
    return f"{v:+.{digits}f}" if signed else f"{v:.{digits}f}"


def _le(a, b) -> Optional[bool]:
    """a <= b, None if either is unknown (inf is a value: never recovered)."""
    if a is None or b is None or math.isnan(a) or math.isnan(b):
        return None
    return bool(a <= b)


def _mean(vals: Sequence[float]) -> float:
    vals = [v for v in vals if v is not None and math.isfinite(v)]
    return float(np.mean(vals)) if vals else float("nan")


# ---------------------------------------------------------------------------------------------
# BROAD: rates, post-motion, drops
# ---------------------------------------------------------------------------------------------
def _broad_means(rs: List[dict], keys: Sequence[str]) -> Dict[str, object]:
    """Mean total over the trials every key has a finite score on."""
    common = [r for r in rs if all(k in r["scores"] and math.isfinite(r["scores"][k]["total"]) for k in keys)]
    out = {k: _mean([r["scores"][k]["total"] for r in common]) for k in keys}
    out["n"] = len(common)
    return out


def _rate_label(tf, rate_hz: float) -> str:
    return f"{rate_hz:.1f} Hz (resampled)" if tf.resample_hz is not None else f"{rate_hz:.1f} Hz (1/{tf.decimate})"


def rate_rows(results: List[dict]) -> List[Row]:
    rows: List[Row] = []
    by_tf = {}
    for r in results:
        if r["kind"] == "broad" and r["role"] == "set" and r["transform"] in SC.RATE_TRANSFORMS:
            by_tf.setdefault(r["transform"], []).append(r)
    means = {}
    for tf in SC.RATE_TRANSFORMS:
        if tf not in by_tf or len({r["trial"] for r in by_tf[tf]}) < 1:
            continue
        for dim, d in DIMS:
            keys = (f"ours-{d}", f"vqf-online-{d}", f"vqf-{d}")
            m = _broad_means(by_tf[tf], keys)
            means[(tf, dim)] = m
            rows.append(Row(BROAD_PART, f"{_rate_label(tf, by_tf[tf][0]['rate_hz'])} {dim}, {m['n']} trials",
                            _f(m[keys[0]]), _f(m[keys[1]]), _f(m[keys[2]]),
                            "ours <= VQF online", _le(m[keys[0]], m[keys[1]]), dict(m)))
    tf3, tol = SC.SAME_AS_NATIVE
    native = SC.RATE_TRANSFORMS[0]
    for dim, d in DIMS:
        if (tf3, dim) in means and (native, dim) in means:
            a, b = means[(tf3, dim)], means[(native, dim)]
            diff = {k: a[k] - b[k] for k in (f"ours-{d}", f"vqf-online-{d}")}
            rows.append(Row(BROAD_PART, f"1/{tf3.decimate} of the rate minus native, {dim}",
                            _f(diff[f"ours-{d}"], signed=True), _f(diff[f"vqf-online-{d}"], signed=True), "",
                            f"|ours| <= {tol:g}", _le(abs(diff[f"ours-{d}"]), tol), diff))
    return rows


def post_motion_rows(results: List[dict]) -> List[Row]:
    rows = []
    native = [r for r in results if r["kind"] == "broad" and r["role"] == "set" and r["transform"].identity
              and r["post"]]
    for dim, d in DIMS:
        keys = (f"ours-{d}", f"vqf-online-{d}")
        vals = {k: [] for k in keys}
        for r in native:
            if all(k in r["post"] for k in keys):
                for i in range(len(r["post"][keys[0]])):
                    pair = [r["post"][k][i] for k in keys]
                    if all(math.isfinite(v) for v in pair):
                        for k, v in zip(keys, pair):
                            vals[k].append(v)
        if not native:
            continue
        m = {k: _mean(v) for k, v in vals.items()}
        rows.append(Row("after motion stops (BROAD): mean inclination error 2-12 s after each motion period "
                        "followed by >= 12 s of rest (deg)", f"{dim}, {len(vals[keys[0]])} periods",
                        _f(m[keys[0]]), _f(m[keys[1]]), "", "ours <= VQF online",
                        _le(m[keys[0]], m[keys[1]]), dict(m, n=len(vals[keys[0]]))))
    return rows


def drop_rows(results: List[dict]) -> List[Row]:
    rows = []
    drops = [r for r in results if r["kind"] == "broad" and r["transform"].drop > 0]
    for dr in drops:
        base = next((r for r in results if r["kind"] == "broad" and r["transform"].identity
                     and r["trial"] == dr["trial"]), None)
        if base is None:
            continue
        tf = dr["transform"]
        for dim, d in DIMS[::-1]:
            keys = (f"ours-{d}", f"vqf-online-{d}")
            if not all(k in dr["scores"] and k in base["scores"] for k in keys):
                continue
            delta = {k: dr["scores"][k]["total"] - base["scores"][k]["total"] for k in keys}
            rows.append(Row(f"dropped samples (BROAD {dr['trial']}): total RMSE minus that without drops (deg)",
                            f"{100 * tf.drop:g}% dropped, gyro {tf.drop_gyro}, {dim}", _f(delta[keys[0]], signed=True),
                            _f(delta[keys[1]], signed=True), "", "ours <= VQF online",
                            _le(delta[keys[0]], delta[keys[1]]), delta))
    return rows


# ---------------------------------------------------------------------------------------------
# Simulations
# ---------------------------------------------------------------------------------------------
def _cells(results: List[dict], part: str):
    out: Dict[tuple, List[dict]] = {}
    for r in results:
        if r["kind"] == part:
            out.setdefault((r["rate_hz"], r["peak"]), []).append(r)
    return out


def _q3(q: Dict[str, float]) -> str:
    return f"{_f(q['median'])} / {_f(q['p90'])} / {_f(q['max'])}"


def motion_rows(results: List[dict]) -> List[Row]:
    rows = []
    t = SC.TARGETS
    for part in ("flips", "tumbles"):
        for (rate, peak), rs in sorted(_cells(results, part).items()):
            where = f"{rate:g} Hz {peak:g} deg/s"
            approach = "approach to the vertical 0-5 deg; " if part == "flips" else ""
            part_text = f"{part} ({len(rs)} runs per cell; {approach}deg): median / p90 / max"
            h = {k: R.quantiles([r["per"][k]["heading_change"] for r in rs]) for k in ("ours-6d", "vqf-online-6d")}
            ok = None if not h["ours-6d"]["n"] else bool(h["ours-6d"]["p90"] <= t["heading_p90"]
                                                         and h["ours-6d"]["max"] <= t["heading_max"])
            rows.append(Row(part_text, f"{where}: 6D heading change", _q3(h["ours-6d"]),
                            _q3(h["vqf-online-6d"]), "", f"p90 <= {t['heading_p90']:g}, max <= {t['heading_max']:g}",
                            ok, h))
            p = {k: R.quantiles([r["per"][k]["peak"] for r in rs]) for k in ("ours-9d", "vqf-online-9d")}
            rows.append(Row(part_text, f"{where}: 9D peak total error", _q3(p["ours-9d"]),
                            _q3(p["vqf-online-9d"]), "", f"max <= {t['peak_9d']:g}",
                            None if not p["ours-9d"]["n"] else bool(p["ours-9d"]["max"] <= t["peak_9d"]), p))
    pooled = {}
    for key in ("ours-9d", "ours-6d"):
        counts = [r["per"][key]["coverage"] for r in results if r["kind"] in ("flips", "tumbles")
                  and "coverage" in r["per"][key]]
        pooled[key] = R.pool_coverage(counts)
    if pooled["ours-9d"] or pooled["ours-6d"]:
        cells = [v for key in pooled for v in pooled[key].values()]
        text = " | ".join("/".join(f"{v:.1f}" for v in pooled[k].values()) for k in pooled)
        rows.append(Row("flips and tumbles: coverage of our reported 3 sigma over every run together (%)",
                        "9D roll/pitch/yaw | 6D roll/pitch", text, "", "", f">= {t['coverage']:g} each",
                        bool(min(cells) >= t["coverage"]), pooled))
    return rows


def _mm(vals: Sequence[float]) -> Dict[str, float]:
    q = R.quantiles(vals)
    return {"median": q["median"], "max": q["max"], "n": q["n"]}


def _mmtext(q: Dict[str, float], digits: int = 1) -> str:
    return f"{_f(q['median'], digits)} ({_f(q['max'], digits)})"


def glitch_rows(results: List[dict]) -> List[Row]:
    rows = []
    sizes = sorted({r["glitch_deg"] for r in results if r["kind"] == "glitch"})
    for g in sizes:
        rs = [r for r in results if r["kind"] == "glitch" and r["glitch_deg"] == g]
        for dim, d, what in (("9D", "9d", "total"), ("6D", "6d", "inclination")):
            q = {k: _mm([r["per"][k]["recovery_s"] for r in rs]) for k in (f"ours-{d}", f"vqf-online-{d}")}
            rows.append(Row(f"glitch at rest (about a horizontal axis, {GLITCH_HZ}): seconds until the error "
                            f"stays below {R.RECOVERY_DEG:g} deg, median (max) of {len(rs)}",
                            f"{g:g} deg, {dim} {what}", _mmtext(q[f"ours-{d}"]),
                            _mmtext(q[f"vqf-online-{d}"]), "", "ours <= VQF online",
                            _le(q[f"ours-{d}"]["median"], q[f"vqf-online-{d}"]["median"]), q))
    return rows


def gap_rows(results: List[dict]) -> List[Row]:
    rs = [r for r in results if r["kind"] == "gap"]
    if not rs:
        return []
    what = (f"{SC.GAP['gap_s']:g} s gap in a {SC.GAP['peak_rate_deg_s']:g} deg/s rotation at {SC.GAP['rate_hz']:g} Hz, "
            f"median (max) of {len(rs)}")
    rows = []
    for name, label in (("after", "9D total error right after (deg)"),
                        ("later", f"9D total error {SC.GAP_LATER_S:g} s later (deg)")):
        q = {k: _mm([r["per"][k][name] for r in rs]) for k in ("ours-9d", "vqf-online-9d")}
        rows.append(Row(what, label, _mmtext(q["ours-9d"]),
                        _mmtext(q["vqf-online-9d"]), "", "ours <= VQF online",
                        _le(q["ours-9d"]["median"], q["vqf-online-9d"]["median"]), q))
    sig = np.array([r["per"]["ours-9d"]["sigma_deg"] for r in rs], float)
    err = np.array([r["per"]["ours-9d"]["after"] for r in rs], float)
    covered = np.isfinite(err) & (err <= 3.0 * np.sqrt(np.sum(sig ** 2, axis=1)))
    med = np.median(sig, axis=0)
    rows.append(Row(what, "our sigma r/p/y right after (deg); runs with error <= 3 sigma",
                    "/".join(f"{v:.1f}" for v in med) + f"; {int(covered.sum())} of {len(rs)}", "", "",
                    "every run", bool(covered.all()), {"sigma_median_deg": med.tolist(),
                                                      "covered": int(covered.sum()), "runs": len(rs)}))
    return rows


def rows(results: List[dict]) -> List[Row]:
    return (rate_rows(results) + motion_rows(results) + post_motion_rows(results) + glitch_rows(results)
            + drop_rows(results) + gap_rows(results))


def format_table(rs: List[Row]) -> str:
    head = ["", "ours", "VQF online", "VQF offline", "target", "result"]
    lines: List[str] = []
    body = []
    for r in rs:
        res = "n/a" if r.passed is None else ("pass" if r.passed else "MISS")
        body.append([r.measure, r.ours, r.online, r.offline, r.target, res])
    table = _table(head, body) if body else ["(no rows)"]
    lines.append(table[0])
    part = None
    for r, line in zip(rs, table[2:]):
        if r.part != part:
            lines.append(r.part)
            part = r.part
        lines.append("  " + line)
    passed = sum(r.passed is True for r in rs)
    missed = sum(r.passed is False for r in rs)
    lines.append(f"{passed} pass, {missed} miss, {len(rs) - passed - missed} n/a of {len(rs)} rows")
    return "\n".join(lines)


def as_json(rs: List[Row]) -> List[Dict[str, object]]:
    return [asdict(r) for r in rs]
