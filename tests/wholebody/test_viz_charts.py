"""The page's charts (wholebody.viz.page.Chart, Scene.add_chart, wholebody.viz.push_charts): an estimate with its
band against the truth over time, the estimator's events marked, a cursor that follows the page's time."""

from __future__ import annotations

import math
import re
import time
from types import SimpleNamespace

import numpy as np
import pytest

from wholebody.viz import Scene, SceneError
from wholebody.viz.browser import find_chromium, screenshot
from wholebody.viz.page import CHART_HEIGHT, CHART_LEFT, CHART_RIGHT, CHART_WIDTH, Chart, chart_svg, nice_scale
from wholebody.viz.push_charts import estimate_charts, estimate_marks


def _points(svg: str, colour: str, tag: str = "polyline") -> list[np.ndarray]:
    """Return the point lists (k, 2) of the SVG's elements `tag` stroked (or filled) with `colour`."""
    out = []
    for m in re.finditer(rf'<{tag} points="([^"]+)"[^>]*"{colour}"', svg):
        out.append(np.array([[float(v) for v in p.split(",")] for p in m.group(1).split()]))
    return out


def test_a_chart_maps_time_and_value_onto_its_plot():
    """A ramp from 10 to 20 over 0-10 s against a truth of 15: the ramp's ends at the plot's left and right edges,
    the truth at its middle, a load change at 5 s in the middle column, the cursor at the left edge."""
    t = np.linspace(0.0, 10.0, 101)
    chart = Chart("mass", "kg", t, 10.0 + t, np.full(101, 0.5), np.full(101, 15.0), ((5.0, "change"),))
    lo, hi = chart.y_range()
    assert (lo, hi) == pytest.approx((8.4, 21.6))  # the ramp +- its 0.5 kg std, 10 % of that 11 kg either side
    svg = chart_svg(chart, 0)
    (ramp,) = _points(svg, "#c51bd8")
    right, top, bottom = CHART_WIDTH - CHART_RIGHT, 16, CHART_HEIGHT - 14
    y = lambda v: bottom - (v - lo) / (hi - lo) * (bottom - top)  # noqa: E731
    np.testing.assert_allclose(ramp[0], [CHART_LEFT, y(10.0)], atol=0.06)
    np.testing.assert_allclose(ramp[-1], [right, y(20.0)], atol=0.06)
    (truth,) = _points(svg, "#1f3fbf")
    np.testing.assert_allclose(truth[:, 1], y(15.0), atol=0.06)
    (band,) = _points(svg, "#c51bd8", "polygon")
    assert band[:, 1].min() == pytest.approx(y(20.5), abs=0.06) and band[:, 1].max() == pytest.approx(y(9.5), abs=0.06)
    x_mark = float(re.search(r'<line x1="([0-9.]+)"[^>]*"#e65100"', svg).group(1))
    assert x_mark == pytest.approx((CHART_LEFT + right) / 2, abs=0.06)
    assert 'id="cartpush-cursor-0"' in svg


def test_the_y_range_leaves_out_the_start_and_what_follows_a_loss():
    """An estimate at 100 for 2 s, then 20, then -50 after a loss at 15 s, against a truth of 21: the range is
    20-21 padded."""
    t = np.linspace(0.0, 20.0, 201)
    est = np.where(t < 2.0, 100.0, np.where(t > 15.0, -50.0, 20.0))
    chart = Chart("m", "kg", t, est, None, np.full(201, 21.0), settle=5.0, until=15.0)
    lo, hi = chart.y_range()
    assert 19.0 < lo < 20.0 and 21.0 < hi < 22.0
    # an unexcited parameter's std (100) widens the range by at most the span the lines cover (1.05: 5 % of 21)
    wide = Chart("m", "kg", t, est, np.full(201, 100.0), np.full(201, 21.0), settle=5.0, until=15.0).y_range()
    assert wide == pytest.approx((20.0 - 1.05 - 0.441, 21.0 + 1.05 + 0.441))  # padded by 2 % of 22.05


def test_gaps_split_the_estimate_and_long_series_are_decimated():
    t = np.linspace(0.0, 100.0, 10001)
    est = np.sin(t)
    est[5000:5100] = np.nan
    runs = _points(chart_svg(Chart("m", "kg", t, est), 0), "#c51bd8")
    assert len(runs) == 2 and sum(len(r) for r in runs) <= 600


def test_add_chart_checks_its_input():
    with Scene(["shopping_cart"]) as scene:
        with pytest.raises(SceneError, match="unknown mark kinds"):
            scene.add_chart("m", "kg", [0.0, 1.0], [1.0, 2.0], marks=[(0.5, "boom")])
        with pytest.raises(SceneError, match="as many as the estimate"):
            scene.add_chart("m", "kg", [0.0, 1.0, 2.0], [1.0, 2.0])
        chart = scene.add_chart("m", "kg", [0.0, 1.0], [1.0, 2.0], std=0.1, truth=1.5)
        assert chart.truth is not None and chart.truth.tolist() == [1.5, 1.5] and chart.std.tolist() == [0.1, 0.1]
        assert '<div id="cartpush-charts">' not in scene.static_html()  # a static page has no time to chart
        scene.animate([0.0, 1.0], {"shopping_cart": np.zeros((2, 3))})
        page = scene.static_html()
        assert '<div id="cartpush-charts">' in page and '"span":1.0' in page


def test_forces_too_large_for_every_choice_get_a_round_scale():
    assert nice_scale(np.array([3.5])) == 0.05
    assert nice_scale(np.array([40.0])) == 0.005  # a hospital bed's push: 10 N = 5 cm
    assert nice_scale(np.array([1000.0])) == pytest.approx(2e-4)
    for f in (31.0, 47.0, 99.0, 333.0):
        s = nice_scale(np.array([f]))
        assert s * f <= 0.3 + 1e-12 and s * f > 0.3 / 2.5  # the largest 1-2-5 step within the 30 cm
        assert round(s / 10 ** math.floor(math.log10(s)), 9) in (1.0, 2.0, 5.0)


def _run(estimation: bool = True, lost: float | None = None) -> SimpleNamespace:
    """A push result as the charts read it: 10 s at 100 Hz, a mass estimate settling on 21 kg, CoM (0.3, 0.1) m."""
    t = 0.01 * np.arange(1000)
    m = 21.0 - 5.0 * np.exp(-t)
    phi = np.column_stack([m, 0.3 * m, 0.1 * m, np.zeros_like(t)])
    report = {
        "load_changes": [{"t_change": 4.0, "t_detected": 5.5, "mass_after": 25.0}],
        "runoff_flags": [{"t": 2.0, "kind": "misfit"}],
    }
    config = SimpleNamespace(true_params=SimpleNamespace(m=20.7, dx=0.3, dy=0.15), estimation=estimation)
    return SimpleNamespace(
        t=t,
        phi_hat=phi,
        param_std=np.column_stack([np.full_like(t, 0.4), np.full_like(t, 0.02)]),
        config=config,
        estimator_report=report,
        metrics=SimpleNamespace(tracking_lost_at_s=lost),
    )


def test_a_push_page_charts_mass_and_com_against_the_truth_with_the_events():
    result = _run(lost=8.0)
    assert sorted(estimate_marks(result)) == [(2.0, "runoff"), (4.0, "change"), (5.5, "detected"), (8.0, "lost")]
    with Scene(["shopping_cart"]) as scene:
        estimate_charts(scene, result)
        mass, com_x, com_y = scene._charts
    assert mass.truth is not None and np.all(mass.truth == 20.7) and np.allclose(mass.std, 0.4)
    np.testing.assert_allclose(com_x.estimate, 30.0) and np.testing.assert_allclose(com_y.truth, 15.0)
    np.testing.assert_allclose(com_y.std, 2.0)  # a result with only the CoM's norm: that 1-sigma on both, in cm
    per_axis = _run()
    per_axis.param_std = np.column_stack([np.full_like(per_axis.t, c) for c in (0.4, 0.05, 0.048, 0.014)])
    with Scene(["shopping_cart"]) as scene:
        estimate_charts(scene, per_axis)
        _, com_x, com_y = scene._charts
    np.testing.assert_allclose(com_x.std, 4.8) and np.testing.assert_allclose(com_y.std, 1.4)  # each axis its own
    assert mass.until == 8.0 and mass.settle == 5.0
    with Scene(["shopping_cart"]) as scene:
        estimate_charts(scene, _run(estimation=False))
        assert all(c.std is None and "fixed guess" in c.title for c in scene._charts)


CHROMIUM = find_chromium()


@pytest.mark.skipif(CHROMIUM is None, reason="needs headless Chromium: apt-get install chromium")
def test_the_cursor_follows_the_page_time_in_a_browser(tmp_path):
    """Paused at 2 s and at 8 s of a 10 s page, the chart's cursor (its only black vertical line) is at 20 % and
    80 % of the plot's width."""
    from PIL import Image

    t = np.linspace(0.0, 10.0, 101)
    with Scene(["shopping_cart"]) as scene:
        scene.add_chart("mass", "kg", t, 20.0 + 0.1 * t, truth=20.5)
        scene.animate(t, {"shopping_cart": np.column_stack([0.1 * t, 0 * t, 0 * t])}, fps=10)
        page = scene.save_html(tmp_path / "page.html", controls=False)
    xs = []
    for when in (2.0, 8.0):
        png = tmp_path / f"t{when}.png"
        screenshot(CHROMIUM, page, png, size=(1024, 640), fragment=f"#t={when}", budget_ms=3000)
        rgb = np.asarray(Image.open(png).convert("RGB"), dtype=int)
        rgb = rgb[:, rgb.shape[1] - CHART_WIDTH - 20 : -8]  # the charts sit bottom right, 8 px from the edge
        plot_rows = (rgb.min(axis=2) >= 245).sum(axis=1) > 100  # the plot's white background
        dark = (rgb[plot_rows].max(axis=2) < 170).sum(axis=0)  # the cursor's pixels per column
        xs.append(int(np.argmax(dark)))
    plot = CHART_WIDTH - CHART_LEFT - CHART_RIGHT
    assert xs[1] - xs[0] == pytest.approx(0.6 * plot, abs=3)


def test_run_off_flags_are_ticks_and_a_loss_shades_the_rest_of_the_run():
    t = np.linspace(0.0, 10.0, 101)
    svg = chart_svg(Chart("m", "kg", t, 20.0 + 0 * t, marks=((2.0, "runoff"), (6.0, "lost"))), 0)
    top, right = 16, CHART_WIDTH - CHART_RIGHT
    tick = re.search(r'<line x1="([0-9.]+)" x2="[0-9.]+" y1="([0-9.]+)" y2="([0-9.]+)" stroke="#d50000"[^>]*""/>', svg)
    assert float(tick.group(2)) == top and float(tick.group(3)) == top + 7  # a tick along the top
    shade = re.search(r'<rect x="([0-9.]+)" y="16" width="([0-9.]+)"[^>]*fill="#d50000"', svg)
    x6 = CHART_LEFT + 0.6 * (right - CHART_LEFT)
    assert float(shade.group(1)) == pytest.approx(x6, abs=0.06) and float(shade.group(2)) == pytest.approx(
        right - x6, abs=0.1
    )


@pytest.mark.skipif(CHROMIUM is None, reason="needs headless Chromium: apt-get install chromium")
def test_a_click_on_the_legend_line_folds_the_legend_away(tmp_path):
    """The legend is open when the page opens; a click on its 'legend' line folds it (its entries are hidden) and
    the player stays."""
    from wholebody.viz.browser import DevToolsPage

    t = np.linspace(0.0, 4.0, 41)
    with Scene(["shopping_cart"]) as scene:
        scene.show_trace("path", np.column_stack([t, 0 * t]), label="cyan line: a path")
        scene.animate(t, {"shopping_cart": np.column_stack([0.1 * t, 0 * t, 0 * t])}, fps=10, play=False)
        page = scene.save_html(tmp_path / "page.html", controls=False)
    assert CHROMIUM is not None
    with DevToolsPage(CHROMIUM, page) as browser:
        for _ in range(200):  # until the page has loaded (real time)
            if browser.evaluate("!!document.getElementById('cartpush-legend')"):
                break
            time.sleep(0.05)
        shown = "document.querySelector('#cartpush-legend .cp-row').checkVisibility()"
        assert browser.evaluate("document.getElementById('cartpush-legend').open") is True
        assert browser.evaluate(shown) is True
        browser.click("cartpush-legend-toggle")
        assert browser.evaluate("document.getElementById('cartpush-legend').open") is False
        assert browser.evaluate(shown) is False
        assert browser.evaluate("document.getElementById('cartpush-play').getBoundingClientRect().height") > 5
