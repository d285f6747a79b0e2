"""Write the screenshots of docs/viz.md: every kind of animated page, rendered by headless Chromium.

* ``demo_{start,middle,end}.png``: the page `cartpush demo` writes (scene.html, the run with estimation,
  Traj. 2, optimal contact, 30 s; `wholebody.push.report.build_scene`) at 0 s, half-way and at the end.
  ``#t=<s>`` in the URL opens the page paused at that time, which is how these are taken.
* ``page_push_{1,2}.png``, ``page_scenario_{1,2}.png``, ``page_log_{1,2}.png``: the pages `push --html`,
  `view --scenario 6 --html` and `view LOG --html` (the log imported from the sample bag) opened as a
  user opens them (no fragment: they play), after 1.5 s and after 6 s of the browser's virtual time.
* ``wmra_push_{start,middle}.png``: `push --robot wmra --trajectory 2 --duration 8 --html` at 0 and 4 s.
* ``push_{path,tracking_estimation,arm_torques}.png``: the figures `cartpush demo --out DIR` writes.

Run from the repository root:

    .venv/bin/python docs/img/make_demo_shots.py [--duration 30]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from wholebody.push import build_scene, demo_configs, run_push
from wholebody.viz.browser import find_chromium, screenshot

OUT = Path(__file__).resolve().parent
ROOT = OUT.parents[1]
SIZE = (1024, 768)


def _demo_shots(browser: str, duration: float, tmp: Path) -> None:
    """Write demo_{start,middle,end}.png."""
    result = run_push(demo_configs(duration)["with estimation"])
    with build_scene(result) as scene:
        html = scene.save_html(tmp / "scene.html", controls=False)
        length = scene.animation_duration()
    for name, t in (("start", 0.0), ("middle", length / 2), ("end", length)):
        png = OUT / f"demo_{name}.png"
        screenshot(browser, html, png, size=SIZE, fragment=f"#t={t:.3f}", profile=tmp / "profile")
        print(f"wrote {png} (t = {t:.1f} s)")


def _page_shots(browser: str, tmp: Path) -> None:
    """Write page_{push,scenario,log}_{1,2}.png: each kind of page, playing, at two moments."""
    from cartpush.cli import main

    bag = ROOT / "cartpush" / "ros" / "data" / "sample_push.bag"
    log = tmp / "sample.csv"
    pages = {kind: tmp / f"{kind}.html" for kind in ("push", "scenario", "log")}
    commands = {
        "push": ["push", "--html", str(pages["push"])],
        "scenario": ["view", "--scenario", "6", "--html", str(pages["scenario"])],
        "log": ["view", str(log), "--html", str(pages["log"])],
    }
    topics = ["--pose-topic", "/mocap/cart", "--wrench-topic", "/ft_sensor/wrench"]
    if main(["import", str(bag), "-o", str(log), *topics]) != 0:
        raise SystemExit("could not import the sample bag")
    for kind, args in commands.items():
        if main(args) != 0:
            raise SystemExit(f"cartpush {' '.join(args)} failed")
        for k, budget in ((1, 1500), (2, 6000)):
            png = OUT / f"page_{kind}_{k}.png"
            screenshot(browser, pages[kind], png, size=SIZE, budget_ms=budget, profile=tmp / "profile")
            print(f"wrote {png} (opened without fragment, {budget / 1000:g} s of virtual time)")


def _wmra_shots(browser: str, tmp: Path) -> None:
    """Write wmra_push_{start,middle}.png: the WMRA's push page at 0 and 4 s."""
    from wholebody.push import PushConfig, save_scene

    html = save_scene(run_push(PushConfig(robot="wmra", trajectory=2, duration=8.0)), tmp / "wmra.html")
    for name, t in (("start", 0.0), ("middle", 4.0)):
        png = OUT / f"wmra_push_{name}.png"
        screenshot(browser, html, png, size=SIZE, fragment=f"#t={t:g}", profile=tmp / "profile")
        print(f"wrote {png} (t = {t:g} s)")


def _demo_figures(duration: float) -> None:
    """Write push_{path,tracking_estimation,arm_torques}.png: the demo's figures."""
    from wholebody.push.report import push_figures, save_figure_dict

    runs = {label: run_push(cfg) for label, cfg in demo_configs(duration).items()}
    for path in save_figure_dict(push_figures(runs), OUT, prefix="push_"):
        print(f"wrote {path}")


def main(argv: list[str] | None = None) -> int:
    """Run the pushes, save the pages and their screenshots; return the exit code."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=30.0)
    args = ap.parse_args(argv)
    browser = find_chromium()
    if browser is None:
        print("chromium not found", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        _demo_shots(browser, args.duration, Path(tmp))
        _page_shots(browser, Path(tmp))
        _wmra_shots(browser, Path(tmp))
    _demo_figures(args.duration)
    return 0


if __name__ == "__main__":
    sys.exit(main())
