"""The run figures `cartpush push --out` and `cartpush demo` write (`wholebody.push.report.push_figures`).

A spike (the start transient, the cart running off after a loss) does not set a panel's y range, and what the range
clips is named on the panel; a lost cart's loss is a labelled line on every time chart and a cross on the path; the
legend of `tracking_estimation.png` sits under the panels; every robot's base is on `path.png`; the PNGs are written
at `FIGURE_DPI`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgba
from PIL import Image

from wholebody.push import PushConfig, run_push
from wholebody.push.figure_axes import FIGURE_DPI, Trace, clipped_note, robust_range, robust_ylim
from wholebody.push.report import _distinct_bases, push_figures, save_figure_dict

T_LOST = 5.0
TIME_CHARTS = ("tracking_estimation", "estimate", "hand_wrenches", "arm_torques")


@pytest.fixture(scope="module")
def kept():
    """A short kinematic push, the cart held to the end (about 2 s CPU)."""
    return run_push(PushConfig(trajectory=2, duration=8.0, contact="fixed"))


@pytest.fixture(scope="module")
def lost(kept):
    """The same run with the cart lost at `T_LOST`: from then on it runs off 3 m sideways and the hand pushes 500 N."""
    after = kept.t >= T_LOST
    q_true = kept.q_true.copy()
    q_true[after, 1] += np.linspace(0.0, 3.0, int(after.sum()))
    wrenches = kept.wrenches.copy()
    wrenches[after, 0, 0] = 500.0
    metrics = replace(kept.metrics, tracking_lost_at_s=T_LOST)
    return replace(kept, q_true=q_true, wrenches=wrenches, metrics=metrics)


def test_a_short_spike_does_not_set_the_range_and_is_named():
    t = np.linspace(0.0, 10.0, 1001)
    y = 1.0 + 0.1 * np.sin(t)
    y[100:105] = 100.0  # 0.05 s of a 10 s run
    trace = Trace(t, y, np.ones_like(t, bool))
    lo, hi = robust_range([trace], zero_bottom=True)
    assert lo == 0.0 and 1.1 <= hi < 1.5
    assert clipped_note([trace], lo, hi, "mm") == "clipped: max 100 mm at t = 1.0 s"
    assert clipped_note([Trace(t, -y, trace.keep)], -hi, -lo, "N") == "clipped: min -100 N at t = 1.0 s"
    assert clipped_note([trace], 0.0, 200.0, "mm") == ""
    before = t < 5.0  # samples after a loss set no range: 50 from 5 s on
    assert robust_range([Trace(t, np.where(before, 1.0, 50.0), before)], at_least=3.0)[1] == pytest.approx(3.1)


def test_robust_ylim_sets_the_axes_and_writes_the_note():
    from matplotlib.figure import Figure

    ax = Figure().subplots()
    t = np.linspace(0.0, 10.0, 1001)
    y = np.where(t < 0.05, 40.0, 2.0)  # 5 samples of 1001
    ax.plot(t, y)
    note = robust_ylim(ax, [Trace(t, y, np.ones_like(t, bool))], "kg", zero_bottom=True)
    assert ax.get_ylim()[1] < 3.0 and note == "clipped: max 40 kg at t = 0.0 s"
    assert [x.get_text() for x in ax.texts] == [note]


def test_a_loss_does_not_flatten_the_tracking_error_and_the_hand_force(lost):
    figs = push_figures({"lost": lost})
    before = lost.t < T_LOST
    tracking, force = figs["tracking_estimation"].axes[0], figs["tracking_estimation"].axes[3]
    error = 1e3 * np.hypot(*(lost.q_true[:, :2] - lost.q_desired[:, :2]).T)
    assert error[before].max() <= tracking.get_ylim()[1] < 0.1 * error.max()  # 3 m after the loss: clipped
    assert [x.get_text() for x in tracking.texts if x.get_text().startswith("clipped")] == [
        "clipped: max 3000 mm at t = 8.0 s"
    ]
    assert force.get_ylim()[1] < 100.0 and any("clipped: max 500 N" in x.get_text() for x in force.texts)
    forward = figs["hand_wrenches"].axes[0]
    assert forward.get_ylim()[1] < 100.0 and any("clipped: max 500 N" in x.get_text() for x in forward.texts)


def _loss_marks(ax) -> tuple[list, list]:
    """Return the red vertical lines at `T_LOST` and the texts naming the loss on `ax`."""
    lines = [
        ln
        for ln in ax.get_lines()
        if list(ln.get_xdata()) == [T_LOST, T_LOST] and to_rgba(ln.get_color()) == to_rgba("r")
    ]
    return lines, [x for x in ax.texts if x.get_text().strip() == f"cart lost {T_LOST:.2f} s"]


@pytest.mark.parametrize("name", TIME_CHARTS)
def test_the_loss_is_a_labelled_line_on_every_time_chart(lost, kept, name):
    for ax in push_figures({"lost": lost})[name].axes:
        lines, texts = _loss_marks(ax)
        assert len(lines) == 1 and len(texts) == 1, (name, ax.get_ylabel())
    for ax in push_figures({"kept": kept})[name].axes:
        assert _loss_marks(ax) == ([], [])


def test_the_path_marks_where_the_cart_was_lost(lost, kept):
    ax = push_figures({"lost": lost})["path"].axes[0]
    (cross,) = [ln for ln in ax.get_lines() if ln.get_label() == f"cart lost at {T_LOST:.2f} s, lost"]
    k = int(np.searchsorted(lost.t, T_LOST))
    np.testing.assert_allclose([cross.get_xdata()[0], cross.get_ydata()[0]], lost.q_true[k, :2])
    assert f"cart lost at {T_LOST:.2f} s, lost" in [x.get_text() for x in ax.get_legend().get_texts()]
    assert not any("lost" in ln.get_label() for ln in push_figures({"kept": kept})["path"].axes[0].get_lines())


def test_the_tracking_estimation_legend_is_under_the_panels_not_beside_them(kept):
    fig = push_figures({"first": kept, "second": kept})["tracking_estimation"]
    assert all(ax.get_legend() is None for ax in fig.axes) and len(fig.legends) == 1
    texts = [x.get_text() for x in fig.legends[0].get_texts()]
    assert len(texts) == len(set(texts)) and "first" in texts and "within 1 kg" in texts
    FigureCanvasAgg(fig).draw()
    for ax in fig.axes:
        assert ax.get_position().width > 0.8, "a legend beside the panels squeezes them"
    legend = fig.legends[0].get_window_extent().transformed(fig.transFigure.inverted())
    assert legend.y1 <= min(ax.get_position().y0 for ax in fig.axes)


def test_every_robots_base_is_on_the_path_figure():
    two = run_push(PushConfig(trajectory=1, duration=4.0, contact="fixed", n_arms=2))
    ax = push_figures({"two": two})["path"].axes[0]
    bases = [ln for ln in ax.get_lines() if "base" in ln.get_label()]
    assert [ln.get_label() for ln in bases] == ["robot 1 base, two", "robot 2 base, two"]
    for k, ln in enumerate(bases):
        np.testing.assert_allclose(ln.get_ydata(), two.robot_x[:, k, 1])
    assert bases[0].get_linestyle() != bases[1].get_linestyle()
    assert len(ax.get_legend().get_texts()) == 1 + 1 + 2
    one_base = np.repeat(two.robot_x[:, :1], 2, axis=1)  # one base holding both hands: drawn once
    assert _distinct_bases(one_base) == [0] and _distinct_bases(two.robot_x) == [0, 1]


def test_figures_are_written_at_the_figure_dpi(tmp_path):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4.0, 3.0))
    fig.subplots().plot([0, 1], [0, 1])
    (path,) = save_figure_dict({"f": fig}, tmp_path)
    with Image.open(path) as png:
        assert png.size == (4 * FIGURE_DPI, 3 * FIGURE_DPI)
        assert png.info["dpi"] == pytest.approx((FIGURE_DPI, FIGURE_DPI), abs=0.5)
    assert FIGURE_DPI >= 150
