"""attekf.plots: what the per-trial figure must show (truth visible over the estimate, no
wrap jumps, clipped errors marked, one time axis, disturbance episodes shaded), on simulated
recordings and on a real BROAD trial."""

from __future__ import annotations

import numpy as np
import pytest

from attekf import evaluate as ev
from attekf import plots
from attekf.sim import SimConfig, simulate


@pytest.fixture(scope="module")
def disturbed():
    rec = simulate(SimConfig(duration_s=30.0, rate_hz=100.0, seed=2, lin_acc_m_s2=3.0,
                             mag_disturbance_uT=30.0, disturbance_every_s=10.0))
    tr, _ = ev.evaluate_run(rec)
    return rec, tr


def test_unwrap_and_branch():
    a = np.array([170.0, 179.0, -179.0, -170.0, np.nan, -160.0])
    u = plots.unwrap_deg(a)
    assert np.all(np.abs(np.diff(u[np.isfinite(u)])) < 20) and np.isnan(u[4])
    assert u[2] == pytest.approx(181.0)
    # an estimate on the other branch (-190 = 170) is drawn next to the truth
    est = np.array([-190.0, -181.0, 181.0, 190.0, 195.0, 200.0])
    on = plots.on_branch(est, u)
    assert np.all(np.abs(on - np.where(np.isfinite(u), u, on)) < 10)
    # where the truth is missing the shift of the neighbours holds
    assert on[4] == pytest.approx(195.0)


def test_marks_and_limits():
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots()
    t = np.arange(1000.0)
    y = np.zeros(1000)
    y[10:20] = 50.0
    y[500] = -70.0
    assert plots.mark_beyond(ax, t, y, -5.0, 5.0, "r") == 11
    plt.close(fig)
    scored = np.ones(1000, bool)
    assert plots.limit(np.full(1000, 2.0), scored) == pytest.approx(plots.ZOOM * 2.0)
    assert plots.limit(np.full(1000, 2.0), scored, floor=4.0) == pytest.approx(plots.ZOOM * 4.0)


def test_figure_layout_truth_on_top_and_episodes(disturbed):
    rec, tr = disturbed
    assert [k for k, _a, _b in tr.episodes].count("linear_acceleration") >= 2
    fig = plots.trial_figure(tr)
    try:
        fig.canvas.draw()    # constrained layout places the axes
        axes = np.array(fig.axes[:8]).reshape(4, 2)
        ref = axes[0, 0]
        for ax in axes.flat:
            assert ax.get_shared_x_axes().joined(ref, ax)        # one time axis
            assert ax.get_xlim() == pytest.approx(ref.get_xlim())
        for col in (0, 1):                                        # the columns line up
            x0 = {round(ax.get_position().x0, 3) for ax in axes[:, col]}
            x1 = {round(ax.get_position().x1, 3) for ax in axes[:, col]}
            assert len(x0) == 1 and len(x1) == 1, (col, x0, x1)
        for k in range(3):
            lines = {ln.get_label(): ln for ln in axes[k, 0].get_lines()}
            assert lines["truth"].get_zorder() > lines["estimate"].get_zorder()
            assert lines["truth"].get_linewidth() < lines["estimate"].get_linewidth()
        # every episode is a band in every panel
        from matplotlib.colors import to_rgba
        orange = to_rgba("tab:orange", 0.13)
        bands = [p for p in axes[2, 1].patches if np.allclose(p.get_facecolor(), orange)]
        assert len(bands) == sum(k == "linear_acceleration" for k, _a, _b in tr.episodes)
    finally:
        import matplotlib.pyplot as plt
        plt.close(fig)


def test_yaw_drawn_without_wrap_jumps(disturbed):
    rec, tr = disturbed
    ref, est = plots.display_angles(tr)
    for a in (ref[:, 2], est[:, 2]):
        d = np.diff(a[np.isfinite(a)])
        assert np.abs(d).max() < 20.0           # 100 Hz: never a 360 deg jump
    both = np.isfinite(ref[:, 2]) & np.isfinite(est[:, 2])
    assert np.abs(est[both, 2] - ref[both, 2]).max() < 30.0     # same branch


def test_six_d_heading_offset_taken_out_of_the_drawn_yaw(disturbed):
    rec, _ = disturbed
    tr, _ = ev.evaluate_run(rec, use_mag=False)
    ref, est = plots.display_angles(tr)
    both = np.isfinite(ref[:, 2]) & np.isfinite(est[:, 2]) & tr.scored
    assert np.median(np.abs(est[both, 2] - ref[both, 2])) < 5.0


def test_plot_file_and_episodes_from_a_csv(disturbed, tmp_path):
    """The episodes survive the CSV round trip (as '# episodes:' metadata)."""
    from attekf.io import read_recording, write_recording
    rec, tr = disturbed
    write_recording(str(tmp_path / "d.csv"), rec)
    back = read_recording(str(tmp_path / "d.csv"))
    got = ev.recording_episodes(back)
    assert [k for k, _a, _b in got] == [k for k, _a, _b in tr.episodes]
    np.testing.assert_allclose([(a, b) for _k, a, b in got], [(a, b) for _k, a, b in tr.episodes], atol=1e-6)
    path = plots.plot_trial(tr, str(tmp_path / "p" / "d.png"))
    assert open(path, "rb").read(8) == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in (tmp_path / "p").iterdir()) == ["d.png"]


def test_broad_trial_plot(broad_trial, tmp_path):
    """A real trial: yaw continuous where the truth is, clipped errors counted in the panel."""
    from attekf.io import read_recording
    rec = read_recording(str(broad_trial)).slice(0, 20000)
    tr, _ = ev.evaluate_run(rec)
    ref, est = plots.display_angles(tr)
    d = np.diff(ref[:, 2])
    assert np.nanmax(np.abs(d)) < 30.0
    fig = plots.trial_figure(tr)
    try:
        texts = [t.get_text() for ax in fig.axes for t in ax.texts]
        beyond = [t for t in texts if "beyond" in t]
        assert all("samples beyond" in t for t in beyond)
        # every Euler error panel counts exactly the samples outside its range (the range
        # widens to show the 3-sigma band, so with a band wider than the error there are none)
        for k, ang in enumerate(("roll", "pitch", "yaw")):
            ax = next(a for a in fig.axes if a.get_ylabel() == f"{ang} error (°)")
            lim = ax.get_ylim()[1]
            err = np.degrees(tr.err_euler[:, k])
            n = int((np.isfinite(err) & (np.abs(err) > lim)).sum())
            notes = [t.get_text() for t in ax.texts if "beyond" in t.get_text()]
            assert (notes == []) if n == 0 else (len(notes) == 1 and notes[0].startswith(f"▲▼ {n} of ")), (ang, n, notes)
    finally:
        import matplotlib.pyplot as plt
        plt.close(fig)


def test_progress_counts_are_integers():
    from tqdm import tqdm
    from attekf import progress
    pb = progress.bar(12, "bench", unit="run")
    text = tqdm.format_meter(n=1, total=12, elapsed=3.0, unit="run", unit_scale=pb.format_dict["unit_scale"])
    pb.close()
    assert "| 1/12 [" in text, text       # unit scaling would print 1.00/12.0
