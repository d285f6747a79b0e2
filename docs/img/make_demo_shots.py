"""Write docs/img/demo_{start,middle,end}.png: the page `cartpush demo` writes (scene.html), in headless Chromium.

The demo's run with estimation (Traj. 2, optimal contact, 30 s) is animated by
`wholebody.push.report.build_scene`; the page opens paused at the first frame and
its camera follows the robot and the cart. ``#t=<s>`` in the URL seeks, which is
how the three screenshots are taken. Run from the repository root:

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


def main(argv: list[str] | None = None) -> int:
    """Run the demo's push, save its page and three screenshots; return the exit code."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=30.0)
    args = ap.parse_args(argv)
    browser = find_chromium()
    if browser is None:
        print("chromium not found", file=sys.stderr)
        return 1
    result = run_push(demo_configs(args.duration)["with estimation"])
    with tempfile.TemporaryDirectory() as tmp, tempfile.TemporaryDirectory() as profile:
        with build_scene(result) as scene:
            html = scene.save_html(Path(tmp) / "scene.html", controls=False)
            duration = scene.animation_duration()
        for name, t in (("start", 0.0), ("middle", duration / 2), ("end", duration)):
            png = OUT / f"demo_{name}.png"
            screenshot(browser, html, png, fragment=f"#t={t:.3f}", profile=Path(profile))
            print(f"wrote {png} (t = {t:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
