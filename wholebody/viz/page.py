"""The offline page of a scene: the viewer, the camera script, the player (play/pause, time) and the legend.

`static_html` turns recorded Meshcat commands into one self-contained HTML page.
An animated page **plays when opened** and loops; its overlay (bottom left) has
a pause/play button (the space bar toggles it too), the animation time, live
read-outs (e.g. the hand force in N) and the legend saying what each colour and
arrow means (folded when the window is too small for it). ``#t=<s>`` in the URL opens the page paused at that time,
``#pause`` opens it paused at the start, ``#t=<s>&play`` plays from there.
"""

from __future__ import annotations

import base64
import gzip
import html as _html
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import meshcat
import numpy as np

from wholebody.viz.lowering import replay_js

if TYPE_CHECKING:
    from wholebody.viz.scene import Camera

_VIEWER_JS = Path(meshcat.__file__).resolve().parent / "viewer" / "dist" / "main.min.js"
#: three.js's THREE.LoopRepeat (the page loops its animation).
_LOOP_REPEAT = 2201


@dataclass(frozen=True)
class LegendEntry:
    """One legend line: a colour swatch (0xRRGGBB), its shape (``"arrow"``, ``"sphere"``, ``"line"``, ``"dot"``) and text."""

    color: int
    shape: str
    text: str


@dataclass(frozen=True)
class Readout:
    """A number shown live on an animated page: ``label: value unit`` at the animation time (samples t, values)."""

    label: str
    unit: str
    t: np.ndarray
    values: np.ndarray
    digits: int = 1

    def as_json(self) -> dict:
        """Return the readout as plain lists (times relative to the first sample, rounded)."""
        t = np.asarray(self.t, float)
        v = np.asarray(self.values, float)
        return {
            "label": self.label,
            "unit": self.unit,
            "digits": int(self.digits),
            "t": [round(float(x), 3) for x in t - t[0]],
            "v": [round(float(x), self.digits + 2) if math.isfinite(x) else None for x in v],  # null: shown as "-"
        }


#: the kinds of time mark a chart draws: (SVG colour, dash pattern, what the legend under the chart calls it)
MARKS = {
    "made": ("#1f3fbf", "2 2", "load put in / taken out (truth)"),
    "change": ("#e65100", "", "load change"),
    "detected": ("#e65100", "4 3", "its detection"),
    "runoff": ("#d50000", "", "run-off flag (tick)"),
    "lost": ("#d50000", "2 2", "cart lost"),
}
#: chart colours: the estimate and its band (the CoM marker's magenta), the truth (the true CoM's blue)
CHART_ESTIMATE, CHART_TRUTH = "#c51bd8", "#1f3fbf"
#: most points of a chart's polylines (longer series are decimated)
CHART_POINTS = 600
#: a chart's size and margins (px): the plot spans x from CHART_LEFT to CHART_WIDTH - CHART_RIGHT
CHART_WIDTH, CHART_HEIGHT, CHART_LEFT, CHART_RIGHT = 300, 86, 44, 6


@dataclass(frozen=True)
class Chart:
    """A small time plot on an animated page: an estimate with its band (+-1 std) against the truth, time marks
    (`MARKS`: load changes, run-off flags, the loss of the cart) and a cursor at the page's time.

    ``t``, ``estimate``, ``std`` and ``truth`` are samples (N,); ``std``/``truth`` may be None; NaN values are gaps.
    ``marks``: (time, kind) pairs: load changes are lines across the plot, run-off flags ticks along its top (a run
    may raise dozens), the loss of the cart shades the rest of the run. The y range covers the truth and the
    estimate +- its median std from ``settle`` s after the start (the start transient may leave it) to ``until`` (a
    lost cart's estimate may run off); the band is clipped to it.
    """

    title: str
    unit: str
    t: np.ndarray
    estimate: np.ndarray
    std: np.ndarray | None = None
    truth: np.ndarray | None = None
    marks: tuple[tuple[float, str], ...] = ()
    settle: float = 0.0
    until: float = math.inf

    def y_range(self) -> tuple[float, float]:
        """Return the plotted (low, high) values: the truth and the settled estimate, widened by the estimate's
        median std up to the span they cover (a band of an unexcited parameter would flatten the lines), padded by
        10 % (at least 1e-3)."""
        t = np.asarray(self.t, float)
        keep = (t >= t[0] + self.settle) & (t <= self.until)
        keep = keep if keep.any() else np.ones(len(t), bool)
        v = np.asarray(self.estimate, float)[keep]
        if self.truth is not None:
            v = np.r_[v, np.asarray(self.truth, float)]
        v = v[np.isfinite(v)]
        lo, hi = (float(v.min()), float(v.max())) if v.size else (0.0, 1.0)
        std = np.asarray(self.std, float)[keep] if self.std is not None else np.zeros(0)
        std = std[np.isfinite(std)]
        width = min(float(np.median(std)), max(hi - lo, 0.05 * max(abs(lo), abs(hi)))) if std.size else 0.0
        lo, hi = lo - width, hi + width
        pad = max(0.1 * (hi - lo), 1e-3, 0.02 * max(abs(lo), abs(hi)))
        return lo - pad, hi + pad

    def cursor_span(self) -> dict:
        """Return what the page's script needs to place the cursor: the chart's time span (s) and x pixel range."""
        t = np.asarray(self.t, float)
        return {"span": max(float(t[-1] - t[0]), 1e-9), "x0": CHART_LEFT, "x1": CHART_WIDTH - CHART_RIGHT}


def _polyline(x: np.ndarray, y: np.ndarray) -> list[str]:
    """Return SVG point lists of the finite runs of (x, y), decimated to at most `CHART_POINTS` points."""
    stride = max(1, int(math.ceil(len(x) / CHART_POINTS)))
    x, y = x[::stride], y[::stride]
    runs, current = [], []
    for a, b in zip(x, y):
        if math.isfinite(a) and math.isfinite(b):
            current.append(f"{a:.1f},{b:.1f}")
        elif current:
            runs.append(" ".join(current))
            current = []
    if current:
        runs.append(" ".join(current))
    return runs


def _mark_svg(kind: str, x: float, top: float, bottom: float, right: float) -> list[str]:
    """Return the SVG of a time mark at x: a line across the plot, a tick along its top (a run-off flag), or a
    line and the rest of the run shaded (the loss of the cart)."""
    colour, dash, _ = MARKS[kind]
    end = top + 7 if kind == "runoff" else bottom
    line = (
        f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{top}" y2="{end}" stroke="{colour}" stroke-width="1.3" '
        f'stroke-dasharray="{dash}"/>'
    )
    if kind != "lost":
        return [line]
    return [
        f'<rect x="{x:.1f}" y="{top}" width="{right - x:.1f}" height="{bottom - top}" fill="{colour}" '
        'fill-opacity="0.12"/>',
        line,
    ]


def chart_svg(chart: Chart, index: int) -> str:
    """Return the chart as inline SVG (`Chart`); its cursor line has the id ``cartpush-cursor-<index>``."""
    width, height = CHART_WIDTH, CHART_HEIGHT
    left, right, top, bottom = CHART_LEFT, width - CHART_RIGHT, 16, height - 14
    t = np.asarray(chart.t, float)
    t0, t1 = float(t[0]), float(t[-1]) if t[-1] > t[0] else float(t[0]) + 1.0
    lo, hi = chart.y_range()
    X = lambda v: left + (np.asarray(v, float) - t0) / (t1 - t0) * (right - left)  # noqa: E731
    Y = lambda v: bottom - (np.clip(np.asarray(v, float), lo, hi) - lo) / (hi - lo) * (bottom - top)  # noqa: E731
    parts = [f'<rect x="{left}" y="{top}" width="{right - left}" height="{bottom - top}" fill="#fff" stroke="#999"/>']
    est = np.asarray(chart.estimate, float)
    if chart.std is not None:
        std = np.asarray(chart.std, float)
        ok = np.isfinite(est) & np.isfinite(std)
        if ok.any():
            upper, lower = (
                _polyline(X(t[ok]), Y(est[ok] + std[ok])),
                _polyline(X(t[ok])[::-1], Y(est[ok] - std[ok])[::-1]),
            )
            parts.append(f'<polygon points="{upper[0]} {lower[0]}" fill="{CHART_ESTIMATE}" fill-opacity="0.2"/>')
    if chart.truth is not None:
        for run in _polyline(X(t), Y(chart.truth)):
            parts.append(
                f'<polyline points="{run}" fill="none" stroke="{CHART_TRUTH}" stroke-width="1.5" stroke-dasharray="6 3"/>'
            )
    for run in _polyline(X(t), Y(est)):
        parts.append(f'<polyline points="{run}" fill="none" stroke="{CHART_ESTIMATE}" stroke-width="1.5"/>')
    for when, kind in chart.marks:
        parts += _mark_svg(kind, float(X(min(max(when, t0), t1))), top, bottom, right)
    parts.append(
        f'<line id="cartpush-cursor-{index}" x1="{left}" x2="{left}" y1="{top}" y2="{bottom}" stroke="#111" stroke-width="2"/>'
    )
    digits = max(0, 2 - int(math.floor(math.log10(max(hi - lo, 1e-9)))))
    text = 'font-size="10" fill="#111"'
    parts += [
        f'<text x="{left - 3}" y="{top + 8}" text-anchor="end" {text}>{hi:.{digits}f}</text>',
        f'<text x="{left - 3}" y="{bottom}" text-anchor="end" {text}>{lo:.{digits}f}</text>',
        f'<text x="{left}" y="{height - 2}" {text}>{t0 - t0:.0f} s</text>',
        f'<text x="{right}" y="{height - 2}" text-anchor="end" {text}>{t1 - t0:.0f} s</text>',
        f'<text x="{left}" y="11" {text} font-weight="bold">{_html.escape(chart.title)} [{_html.escape(chart.unit)}]</text>',
    ]
    return f'<svg width="{width}" height="{height}" xmlns="http://www.w3.org/2000/svg">{"".join(parts)}</svg>'


def charts_html(charts: Sequence[Chart]) -> str:
    """Return the charts' panel (bottom right): each chart, then one key to the lines and marks they use; a click on
    its "charts" line folds it away to free the view."""
    if not charts:
        return ""
    kinds = sorted({kind for c in charts for _, kind in c.marks}, key=list(MARKS).index)
    key = [
        f'<span style="color: {CHART_ESTIMATE}">&#9644; estimate</span>',
        f'<span style="color: {CHART_ESTIMATE}; opacity: 0.5">&#9608; +-1 sigma</span>',
        f'<span style="color: {CHART_TRUTH}">- - truth</span>',
    ] + [f'<span style="color: {MARKS[k][0]}">| {MARKS[k][2]}</span>' for k in kinds]
    body = "".join(f"<div>{chart_svg(c, i)}</div>" for i, c in enumerate(charts))
    return (
        '<div id="cartpush-charts"><details id="cartpush-charts-panel" open><summary id="cartpush-charts-toggle">'
        f'charts</summary>{body}<div class="cp-key">{" &nbsp;".join(key)}</div></details></div>'
    )


def camera_js(camera: Camera) -> str:
    """Return JavaScript that points the viewer's camera from `camera.eye` at `camera.target`.

    Meshcat's three.js scene is rotated -90 deg about x (z up) and the camera
    hangs under a node rotated +90 deg, so camera and orbit-control coordinates
    are three.js world coordinates: meshcat (x, y, z) -> (x, z, -y).
    """
    (ex, ey, ez), (tx, ty, tz) = camera.eye, camera.target
    e, t = (", ".join(f"{float(v):.6g}" for v in vec) for vec in ((ex, ez, -ey), (tx, tz, -ty)))
    return f"""(function () {{
  const cam = viewer.camera;
  cam.fov = {float(camera.fov_deg):.6g};
  cam.updateProjectionMatrix();
  cam.position.set({e});
  viewer.controls.target.set({t});
  viewer.controls.update();
  viewer.set_dirty();
}})();
"""


#: The animated page's script (`animation_js` fills in the __NAMES__).
_ANIMATION_JS = """(function () {
  const anim = viewer.animator;
  for (const a of anim.actions) a.setLoop(__LOOP__, Infinity);
  const button = document.getElementById("cartpush-play");
  const clock = document.getElementById("cartpush-time");
  const readouts = __READOUTS__;
  const readoutNodes = readouts.map(function (r, i) { return document.getElementById("cartpush-readout-" + i); });
  const charts = __CHARTS__;
  const cursors = charts.map(function (c, i) { return document.getElementById("cartpush-cursor-" + i); });
  function sample(r, t) {
    let lo = 0, hi = r.t.length - 1;
    if (hi < 0) return NaN;
    while (lo < hi) { const mid = (lo + hi + 1) >> 1; if (r.t[mid] <= t) lo = mid; else hi = mid - 1; }
    return r.v[lo];
  }
  function now() {
    if (!anim.actions.length) return 0;
    return anim.actions.reduce(function (m, a) { return Math.max(m, a.time); }, 0);
  }
  function refresh() {
    const t = now();
    if (button) button.textContent = anim.playing ? "\\u275a\\u275a pause" : "\\u25b6 play";
    if (clock) clock.textContent = "t = " + t.toFixed(1) + " / " + anim.duration.toFixed(1) + " s";
    readouts.forEach(function (r, i) {
      const v = sample(r, t);
      if (readoutNodes[i]) readoutNodes[i].textContent = r.label + ": " + (Number.isFinite(v) ? v.toFixed(r.digits) : "-") + " " + r.unit;
    });
    charts.forEach(function (c, i) {
      const x = c.x0 + Math.max(0, Math.min(1, t / c.span)) * (c.x1 - c.x0);
      if (cursors[i]) { cursors[i].setAttribute("x1", x.toFixed(1)); cursors[i].setAttribute("x2", x.toFixed(1)); }
    });
  }
  function seek(t) {
    if (!anim.actions.length) return;
    anim.pause();
    for (const a of anim.actions) {
      a.play(); a.paused = false; a.time = Math.max(0, Math.min(a._clip.duration, t));
    }
    anim.mixer.update(0);
    anim.display_progress(Math.max(0, Math.min(anim.duration, t)));
    viewer.set_dirty();
    refresh();
  }
  anim.seek = seek;
  function toggle() {
    if (anim.playing) anim.pause(); else anim.play();
    refresh();
  }
  if (button) button.addEventListener("click", toggle);
  window.addEventListener("keydown", function (e) {
    if (e.code === "Space" && e.target === document.body) { e.preventDefault(); toggle(); }
  });
  const nodes = __FOLLOW__.map(function (p) { return viewer.scene_tree.find(p).object; });
  const last = viewer.camera.position.clone(), here = last.clone(), tmp = last.clone();
  function centre(out) {
    out.set(0, 0, 0);
    for (const n of nodes) { n.getWorldPosition(tmp); out.add(tmp); }
    return out.multiplyScalar(1 / Math.max(1, nodes.length));
  }
  if (nodes.length) centre(last);
  const update = anim.update.bind(anim);
  anim.update = function () {
    update();
    if (anim.playing) refresh();
    if (!nodes.length) return;
    centre(here);
    if (here.distanceToSquared(last) > 1e-12) {
      tmp.copy(here).sub(last);
      viewer.camera.position.add(tmp);
      viewer.controls.target.add(tmp);
      viewer.controls.update();
      last.copy(here);
      viewer.set_dirty();
    }
  };
  function fromHash() {
    const h = window.location.hash;
    const m = /(?:^#|&)t=([-+0-9.eE]+)/.exec(h);
    const play = /(?:^#|&)play(?:&|$)/.test(h), pause = /(?:^#|&)pause(?:&|$)/.test(h);
    if (m) seek(parseFloat(m[1]));
    else if (pause) seek(0);
    if (play || (!m && !pause && __AUTOPLAY__)) anim.play();
    refresh();
  }
  window.addEventListener("hashchange", fromHash);
  fromHash();
})();
"""


def animation_js(
    follow: Sequence[str], autoplay: bool = True, readouts: Sequence[Readout] = (), charts: Sequence[Chart] = ()
) -> str:
    """Return JavaScript for an animated page: autoplay and loop, pause button, seek by URL hash, camera follow.

    * The page plays when opened (`autoplay`) and loops; ``#pause`` opens it
      paused at the start, ``#t=12.5`` paused at 12.5 s, ``#t=3&play`` plays
      from 3 s (``#play`` plays a page built with ``autoplay=False``).
    * The overlay's button (id ``cartpush-play``) and the space bar pause and
      resume; the time, the `readouts` and the cursors of the `charts` update every frame.
    * The GUI's time scrubber seeks even while paused.
    * When `follow` names nodes (``"/meshcat/<robot>"``), the camera and its
      orbit target move with the mean world position of those nodes, keeping
      the offset the viewer had (orbiting by mouse still works).
    """
    paths = "[" + ", ".join("[" + ", ".join(f'"{part}"' for part in p.split("/") if part) + "]" for p in follow) + "]"
    data = json.dumps([r.as_json() for r in readouts], separators=(",", ":"))
    cursors = json.dumps([c.cursor_span() for c in charts], separators=(",", ":"))
    return (
        _ANIMATION_JS.replace("__LOOP__", str(_LOOP_REPEAT))
        .replace("__READOUTS__", data)
        .replace("__CHARTS__", cursors)
        .replace("__FOLLOW__", paths)
        .replace("__AUTOPLAY__", "true" if autoplay else "false")
    )


_SWATCH = {
    "arrow": "width: 18px; height: 4px; margin: 0 6px 2px 0;",
    "line": "width: 18px; height: 2px; margin: 0 6px 3px 0;",
    "sphere": "width: 11px; height: 11px; border-radius: 50%; margin: 0 10px -1px 3px;",
    "dot": "width: 7px; height: 7px; border-radius: 50%; margin: 0 12px 1px 5px;",
}


def overlay_html(legend: Sequence[LegendEntry], animated: bool, readouts: Sequence[Readout] = ()) -> str:
    """Return the overlay (bottom left): player and read-outs of an animated page, then the legend; '' when empty.

    The legend is a ``<details>`` block (open; a click on its "legend" line folds it away to free the view); the
    page folds it when it opens in a window too small for it (`FOLD_LEGEND_JS`).
    """
    rows = []
    if animated:
        rows.append(
            '<div class="cp-row"><button id="cartpush-play" type="button">\u25b6 play</button> '
            '<span id="cartpush-time">t = 0.0 s</span></div>'
        )
        rows += [f'<div class="cp-row" id="cartpush-readout-{i}"></div>' for i in range(len(readouts))]
    entries = []
    for e in legend:
        style = _SWATCH.get(e.shape, _SWATCH["line"])
        entries.append(
            f'<div class="cp-row"><span class="cp-swatch" style="{style} background: #{e.color:06x}"></span>'
            f"{_html.escape(e.text)}</div>"
        )
    if entries:
        rows.append(
            '<details id="cartpush-legend" open><summary id="cartpush-legend-toggle">legend</summary>'
            + "".join(entries)
            + "</details>"
        )
    if not rows:
        return ""
    return '<div id="cartpush-overlay">' + "".join(rows) + "</div>"


#: the overlay's open legend may take at most this share of the window's height: taller, the page opens it folded
#: (a 1024 x 768 window: the player, the read-outs and the legend line stay, the scene above them is free)
LEGEND_FOLD_SHARE = 0.25

#: folds the legend when the overlay with it open is taller than `LEGEND_FOLD_SHARE` of the window (run on load,
#: after the read-outs are filled)
FOLD_LEGEND_JS = """(function () {
  const box = document.getElementById("cartpush-overlay"), legend = document.getElementById("cartpush-legend");
  if (box && legend && box.getBoundingClientRect().height > __SHARE__ * window.innerHeight) legend.open = false;
})();
""".replace("__SHARE__", str(LEGEND_FOLD_SHARE))

_OVERLAY_CSS = (
    "#cartpush-overlay {position: absolute; left: 8px; bottom: 8px; max-width: min(520px, 42vw); padding: 5px 8px;"
    " max-height: calc(100vh - 16px); overflow-y: auto; box-sizing: border-box;"
    " font: 11px/1.35 'DejaVu Sans', sans-serif; color: #111; background: rgba(255, 255, 255, 0.85);"
    " border-radius: 4px; z-index: 10;}"
    " .cp-swatch {display: inline-block; vertical-align: middle;}"
    " #cartpush-legend summary, #cartpush-charts summary {cursor: pointer; color: #555;}"
    " #cartpush-play {font: 11px 'DejaVu Sans', sans-serif; min-width: 64px; margin-right: 6px;}"
    " #cartpush-charts {position: absolute; right: 8px; bottom: 8px; padding: 4px 6px;"
    " font: 11px/1.4 'DejaVu Sans', sans-serif; background: rgba(255, 255, 255, 0.85); border-radius: 4px; z-index: 10;}"
    " #cartpush-charts svg {font-family: 'DejaVu Sans', sans-serif; display: block;}"
    " .cp-key {max-width: 300px;}"
)


def static_html(
    commands: Sequence[bytes],
    controls: bool = True,
    camera: Camera | None = None,
    follow: Sequence[str] | None = None,
    animated: bool = False,
    legend: Sequence[LegendEntry] = (),
    autoplay: bool = True,
    readouts: Sequence[Readout] = (),
    charts: Sequence[Chart] = (),
) -> str:
    """Return a self-contained HTML page (viewer JavaScript inlined) replaying `commands`, then setting `camera`.

    An `animated` page gets `animation_js` (plays on open unless `autoplay` is
    False, pause button, ``#t=<s>`` seeks, camera following the nodes `follow`)
    and the overlay shows the player, the `readouts` and the `legend` (folded when the window is too small for it,
    `LEGEND_FOLD_SHARE`); its `charts` (bottom right) plot
    estimates over time with a cursor at the page's time. Each distinct mesh file (any value of 1 KiB or
    more) is written once however many commands carry it (`wholebody.viz.lowering.replay_js`).
    """
    js = _VIEWER_JS.read_text(encoding="utf-8")
    hide = "" if controls else ".dg.main, .dg.ac {display: none !important;}"
    script = animation_js(follow or (), autoplay, readouts, charts) if animated else ""
    return f"""<!DOCTYPE html>
<html>
<head><meta charset="utf-8"><title>cartpush scene</title>
<style>body {{margin: 0;}} #meshcat-pane {{width: 100vw; height: 100vh; overflow: hidden;}} {hide} {_OVERLAY_CSS}</style>
</head>
<body>
<div id="meshcat-pane"></div>
{overlay_html(legend, animated, readouts)}
{charts_html(charts) if animated else ""}
<script>
{js}
</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
{replay_js(commands)}{camera_js(camera) if camera is not None else ""}{script}{FOLD_LEGEND_JS}
</script>
</body>
</html>
"""


def compressed_iframe(page: str, height: int = 420) -> str:
    """Return a ``<div>`` holding an ``<iframe>`` whose page is stored gzipped (about a third of its size).

    The iframe's ``srcdoc`` is a short script that inflates the page with the
    browser's DecompressionStream and writes it: works offline and in exported
    HTML (any browser since 2023). The ``<div>`` keeps IPython from warning
    that an ``<iframe>`` should be an ``IFrame``.
    """
    blob = base64.b64encode(gzip.compress(page.encode("utf-8"), compresslevel=9, mtime=0)).decode("ascii")
    loader = (
        "<script>(async function () {"
        "if (!window.DecompressionStream) {"
        'document.body.textContent = "This Meshcat scene (MeshCat.Viewer page, stored gzipped) needs a browser '
        'with DecompressionStream (Chrome 80, Firefox 113, Safari 16.4 or later)."; return; }'
        f'const b = Uint8Array.from(atob("{blob}"), function (c) {{ return c.charCodeAt(0); }});'
        'const s = new Blob([b]).stream().pipeThrough(new DecompressionStream("gzip"));'
        "const text = await new Response(s).text();"
        "document.open(); document.write(text); document.close();"
        "})();</script>"
    )
    return (
        f'<div class="cartpush-scene"><iframe srcdoc="{_html.escape(loader, quote=True)}" '
        f'style="width: 100%; height: {int(height)}px; border: none" title="Meshcat scene"></iframe></div>'
    )


def nice_scale(
    values: np.ndarray, typical: float = 0.3, choices: Sequence[float] = (0.1, 0.05, 0.03, 0.02, 0.01)
) -> float:
    """Return the largest of `choices` (m per unit) drawing the median of |values| at most `typical` m long.

    A median push force of 3.5 N gets 0.05 m/N (17.5 cm; 10 N = 50 cm); the
    rare large forces are clipped by the caller (`Scene.animate`). Forces too large for every choice (a
    hospital bed's 40 N) get the largest 1-2-5 x 10^k below them (0.005 m/N: 10 N = 5 cm), a number the
    legend can say plainly.
    """
    v = np.abs(np.asarray(values, dtype=float))
    v = v[np.isfinite(v)]
    p50 = float(np.median(v)) if v.size else 0.0
    for s in choices:
        if s * p50 <= typical:
            return float(s)
    raw = typical / p50
    decade = 10.0 ** math.floor(math.log10(raw))
    return float(max(m * decade for m in (1.0, 2.0, 5.0) if m * decade <= raw * (1 + 1e-12)))
