"""The figures' "load change found" marks have a colour of their own, not the colour of the run's lines.

`tracking_estimation.png` and `estimate.png` (`wholebody.push.report.push_figures`) of a run in which the
estimator finds a 10 kg load put in at 4 s: the found change is a black vertical line (`LOAD_CHANGE_FOUND_COLOUR`)
with a triangle of the run's colour near its top, lower for the second run; the legend names it.
"""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.colors import to_rgba

from wholebody.push import PushConfig, run_push
from wholebody.push.load_change import LoadChange
from wholebody.push.report import LOAD_CHANGE_FOUND_COLOUR, push_figures

RUNS = ("with estimation", "again")


@pytest.fixture(scope="module")
def figures():
    run = run_push(PushConfig(trajectory=1, duration=8.0, load_changes=(LoadChange(4.0, 10.0),)))
    found = run.estimator_report["load_changes"]
    assert found, "the estimator found no load change: nothing to draw"
    return found[0]["t_change"], push_figures(dict.fromkeys(RUNS, run))


def _line(ax, label):
    lines = [ln for ln in ax.get_lines() if ln.get_label() == label]
    assert len(lines) == 1, f"{len(lines)} lines labelled {label!r}"
    return lines[0]


@pytest.mark.parametrize(
    ("figure", "panels", "run_line"), [("tracking_estimation", (1, 2), "{}"), ("estimate", (0, 1, 2), "estimate, {}")]
)
def test_load_change_found_has_its_own_colour_and_legend_entry(figures, figure, panels, run_line):
    t_change, figs = figures
    axes = figs[figure].axes
    for p in panels:
        ax = axes[p]
        tops = []
        for i, run in enumerate(RUNS):
            mark = _line(ax, f"load change found, {run}")
            run_colour = to_rgba(_line(ax, run_line.format(run)).get_color())
            assert to_rgba(mark.get_color()) == to_rgba(LOAD_CHANGE_FOUND_COLOUR) != run_colour
            assert to_rgba(mark.get_markerfacecolor()) == run_colour == to_rgba(f"C{i}")
            np.testing.assert_allclose(mark.get_xdata(), t_change)
            tops.append(mark.get_ydata()[mark.get_markevery()[0]])
        assert tops[0] > tops[1], "the second run's triangle hides the first's"
    legend = axes[panels[0]].get_legend() or figs[figure].legends[0]
    texts = [t.get_text().replace("\n", " ") for t in legend.get_texts()]
    assert any(t.startswith("load change found, with") for t in texts), texts
