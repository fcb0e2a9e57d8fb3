#!/usr/bin/env python3
"""Error analyses of the estimator on BROAD that use the ground truth (ANALYSIS ONLY: nothing
here feeds a filter). The figures of docs/accuracy.md, "Findings", come from these.

    scripts/accuracy_analysis.py bias     VQF's offset estimate in motion against our rest offset
    scripts/accuracy_analysis.py gravity  inclination with the accelerometer replaced by the
                                          truth's gravity (no linear acceleration, no
                                          accelerometer error): ours and VQF, online and offline
    scripts/accuracy_analysis.py scale    gyroscope scale factor / misalignment and time offset
                                          fitted against the truth's angular rate
    scripts/accuracy_analysis.py heading  decay of a heading offset put into the estimate by a
                                          phantom gyro rotation about the vertical (ours, VQF online)
    scripts/accuracy_analysis.py vertical 6D: the heading error's change over the motion, and the
                                          part of it the corrections made (the turn about the
                                          vertical between consecutive estimates that the gyro,
                                          less the estimated offset, does not explain)

Options: --data DIR (default $ATTEKF_BROAD_DIR or ../shared/data/broad), --trials LIST,
--set NAME=VALUE (our settings), heading: --trial, --at S, --deg D.
"""
import argparse
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "host_tools"))

from attekf import bench as B          # noqa: E402
from attekf import metrics as M        # noqa: E402
from attekf import native              # noqa: E402


def _ours(rec, settings, six_d=False, gyr=None, acc=None):
    res = native.run_arrays(rec.t, rec.gyr if gyr is None else gyr, rec.acc if acc is None else acc,
                            None if six_d else rec.mag, settings)
    q = res.quat.copy()
    q[~res.aligned] = np.nan
    return q, res


def _incl(rec, q, six_d):
    return B.score(rec, q, six_d)["inclination"]


def _vqf(rec, six_d, online, gyr=None, acc=None):
    import vqf
    g = np.ascontiguousarray(rec.gyr if gyr is None else gyr)
    a = np.ascontiguousarray(rec.acc if acc is None else acc)
    m = None if six_d else np.ascontiguousarray(rec.mag)
    ts = 1.0 / rec.rate_hz
    if online:
        f = vqf.VQF(ts)
        out = f.updateBatch(g, a, m) if m is not None else f.updateBatch(g, a)
    else:
        out = vqf.offlineVQF(g, a, m, ts)
    return np.asarray(out["quat6D" if six_d else "quat9D"]), out


def truth_gravity_acc(rec):
    """Specific force of gravity alone in the body frame from the truth (NaN rows: measured)."""
    ok = np.all(np.isfinite(rec.quat_ref), axis=1)
    acc = rec.acc.copy()
    acc[ok] = M.quat_rotate(M.quat_conj(rec.quat_ref[ok]), np.array([0.0, 0.0, 9.81]))
    return acc


def truth_rate(rec):
    """Body rate (rad/s) from central differences of the truth quaternion; NaN without truth."""
    q = rec.quat_ref.copy()
    for i in range(1, len(q)):
        if np.all(np.isfinite(q[i])) and np.all(np.isfinite(q[i - 1])) and np.dot(q[i], q[i - 1]) < 0:
            q[i] = -q[i]
    dq = (q[2:] - q[:-2]) * (rec.rate_hz / 2.0)
    w = np.full((len(q), 3), np.nan)
    w[1:-1] = 2.0 * M.quat_mul(M.quat_conj(q[1:-1]), dq)[:, 1:]
    return w


def cmd_bias(recs, settings):
    """Does the offset change in motion? VQF's offline estimate (forward-backward, acausal) at the
    start of the motion and its range over the motion, beside the mean raw gyro of the initial
    rest (what a rest average learns)."""
    print("trial  mean gyro, initial rest (deg/s)  VQF offline at motion start  VQF range over the motion")
    for rec in recs:
        _, out = _vqf(rec, False, online=False)
        mov = rec.movement.astype(bool)
        first = int(np.argmax(mov))
        rest = np.degrees(rec.gyr[:first].mean(axis=0)) if first > 0 else np.full(3, np.nan)
        vb = np.degrees(out["bias"])
        print(f"{rec.name[:2]}     {np.array2string(rest, precision=3):28s} {np.array2string(vb[first], precision=3):28s}"
              f" {np.array2string(vb[mov].max(0) - vb[mov].min(0), precision=3)}")


def cmd_gravity(recs, settings):
    print("6D inclination RMSE, deg: measured accelerometer | truth gravity as accelerometer")
    print("trial   ours  vqf-on vqf-off |  ours  vqf-on vqf-off")
    rows = []
    for rec in recs:
        accg = truth_gravity_acc(rec)
        row = []
        for acc in (None, accg):
            row.append(_incl(rec, _ours(rec, settings, True, acc=acc)[0], True))
            for online in (True, False):
                row.append(_incl(rec, _vqf(rec, True, online, acc=acc)[0], True))
        rows.append(row)
        print(f"{rec.name[:2]}    " + "  ".join(f"{v:5.2f}" for v in row[:3]) + " | " + "  ".join(f"{v:5.2f}" for v in row[3:]))
    print("mean  " + "  ".join(f"{v:5.2f}" for v in np.mean(rows, axis=0)[:3]) + " | "
          + "  ".join(f"{v:5.2f}" for v in np.mean(rows, axis=0)[3:]))


def _smooth(x, k):
    out = np.full_like(x, np.nan)
    for j in range(x.shape[1]):
        v = x[:, j]
        ok = np.isfinite(v)
        c = np.concatenate([[0.0], np.cumsum(np.where(ok, v, 0.0))])
        n = np.concatenate([[0], np.cumsum(ok)])
        lo = np.clip(np.arange(len(v)) - k // 2, 0, len(v))
        hi = np.clip(np.arange(len(v)) + k // 2 + 1, 0, len(v))
        cnt = n[hi] - n[lo]
        out[:, j] = np.where(cnt == hi - lo, (c[hi] - c[lo]) / np.maximum(cnt, 1), np.nan)
    return out


def cmd_scale(recs, settings):
    print("gyro = (I + S) w_truth + b, fitted over the movement samples (15-sample means), best integer "
          "time offset of the gyro against the truth")
    for rec in recs:
        wt, gs = _smooth(truth_rate(rec), 15), _smooth(rec.gyr, 15)
        ok = np.all(np.isfinite(wt), 1) & np.all(np.isfinite(gs), 1) & rec.movement.astype(bool)
        best = None
        for lag in range(-6, 7):
            g2 = np.roll(gs, lag, axis=0)
            a = np.hstack([wt[ok], np.ones((ok.sum(), 1))])
            x = np.linalg.lstsq(a, g2[ok], rcond=None)[0]
            rms = float(np.sqrt(np.mean((a @ x - g2[ok]) ** 2)))
            if best is None or rms < best[0]:
                best = (rms, lag, x)
        rms, lag, x = best
        s = x[:3].T - np.eye(3)
        print(f"{rec.name[:2]}  offset {lag:+d} samples, |w| rms {np.degrees(np.sqrt(np.mean(np.sum(wt[ok] ** 2, 1)))):4.0f} "
              f"deg/s, scale {np.array2string(100 * np.diag(s), precision=2)} %, misalignment max "
              f"{100 * np.max(np.abs(s - np.diag(np.diag(s)))):.2f} %, residual {np.degrees(rms):.2f} deg/s")


def cmd_heading(rec, settings, at, deg):
    """A rotation of deg about the vertical over 0.5 s that the truth does not make."""
    dur = 0.5
    k0 = int(at * rec.rate_hz)
    k1 = k0 + int(dur * rec.rate_hz)
    g = rec.gyr.copy()
    for k in range(k0, k1):
        q = rec.quat_ref[k] if np.all(np.isfinite(rec.quat_ref[k])) else rec.quat_ref[k0]
        g[k] += M.quat_rotate(M.quat_conj(q), np.array([0.0, 0.0, 1.0])) * np.radians(deg) / dur

    def heading(q):
        e = M.error_quat_earth(q, rec.quat_ref)
        e = e * np.where(e[:, :1] < 0, -1.0, 1.0)
        return np.degrees(2.0 * np.arctan2(e[:, 3], e[:, 0]))

    ours = heading(_ours(rec, settings, gyr=g)[0]) - heading(_ours(rec, settings)[0])
    vqf = heading(_vqf(rec, False, True, gyr=g)[0]) - heading(_vqf(rec, False, True)[0])
    print(f"{rec.name}: {deg:g} deg heading offset put in at {at:g} s; offset left (deg)")
    for t in (0, 1, 2, 5, 10, 20, 30, 60):
        k = k1 + int(t * rec.rate_hz)
        if k < len(ours):
            print(f"  t + {t:2d} s   ours {ours[k]:6.2f}   vqf-online {vqf[k]:6.2f}")


def _vertical_corrections_deg(q, gyr, bias, dt):
    """Cumulative turn about the vertical (earth z), deg, of q[k+1] against q[k] turned by the
    gyro of sample k+1 less the offset: what the updates added beyond the gyro."""
    w = gyr - (0.0 if bias is None else bias)
    pred = M.quat_mul(q[:-1], M.quat_from_rotvec(w[1:] * dt))
    r = M.quat_mul(q[1:], M.quat_conj(pred))
    r = r * np.sign(r[:, :1] + 1e-300)
    z = 2.0 * r[:, 3]  # small angle
    z[~np.isfinite(z)] = 0.0
    return np.degrees(np.concatenate([[0.0], np.cumsum(z)]))


def cmd_vertical(recs, settings):
    print("trial  6D heading error change over the motion (deg): ours, of it from corrections | VQF online, of it")
    for rec in recs:
        q, res = _ours(rec, settings, six_d=True)
        qv, out = _vqf(rec, True, online=True)
        row = []
        for qq, b in ((q, res.gyro_bias), (qv, out["bias"])):
            e = M.error_quat_earth(qq, rec.quat_ref)
            a = 2.0 * np.arctan2(e[:, 3], e[:, 0])
            a[~np.isfinite(a)] = 0.0
            head = np.degrees(np.unwrap(a))
            corr = _vertical_corrections_deg(qq, rec.gyr, b, 1.0 / rec.rate_hz)
            idx = np.nonzero(rec.movement.astype(bool))[0]
            row += [head[idx[-1]] - head[idx[0]], corr[idx[-1]] - corr[idx[0]]]
        print(f"{rec.name[:2]}     {row[0]:7.2f} {row[1]:7.2f} | {row[2]:7.2f} {row[3]:7.2f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", choices=("bias", "gravity", "scale", "heading", "vertical"))
    ap.add_argument("--data", default=os.environ.get("ATTEKF_BROAD_DIR", os.path.join(ROOT, "..", "shared", "data", "broad")))
    ap.add_argument("--trials")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    ap.add_argument("--trial", default="05", help="heading: the trial (prefix)")
    ap.add_argument("--at", type=float, default=100.0, help="heading: time of the offset, s")
    ap.add_argument("--deg", type=float, default=8.0, help="heading: size of the offset, deg")
    args = ap.parse_args()
    settings = {k: float(v) for k, v in (s.split("=", 1) for s in args.set)}
    if args.what == "heading":
        cmd_heading(B.read_recording(B.find_trials(args.data, args.trial)[0]), settings, args.at, args.deg)
        return 0
    recs = [B.read_recording(p) for p in B.find_trials(args.data, args.trials)]
    {"bias": cmd_bias, "gravity": cmd_gravity, "scale": cmd_scale, "vertical": cmd_vertical}[args.what](recs, settings)
    return 0


if __name__ == "__main__":
    sys.exit(main())
