"""Browser test: headless Chromium renders the static page of the Ridgeback + iiwa pushing the cart.

The second part renders the animated page that `cartpush demo` and `push --html`
write (`wholebody.push.report.build_scene`, here from a short run) at the start,
the middle and the end of its animation (``#t=<s>`` seeks), and checks the robot
and the cart are on screen at each time, where the page's following camera
(`Scene.camera_at`) puts them, against the same page with both hidden; and that a
10 N hand force is a visible arrow there.

The third part opens each kind of animated page the command line writes (`push --html`,
`view --scenario N --html`, `view LOG --html`) as a user would, without a URL fragment,
and checks that it moves: two screenshots taken at different times differ, the page's
clock advances and its button offers "pause"; with ``#pause`` it stands still.

The screenshot must differ clearly from the screenshot of an empty scene (same
camera) where the robot and the cart stand — positions projected with the
camera the page sets — and show their colours there: the Ridgeback yellow,
the iiwa orange, the cart's handle red and its basket grey. Needs the Debian
package `chromium` (`make test` and .ci/run install it when they can); without it the
module is skipped with one line saying what to install, unless CARTPUSH_REQUIRE_BROWSER=1
(set by .ci/run), where a missing browser is an error.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from robots.shopping_cart import CART_HANDLE_X, CART_HANDLE_Z_B, CART_WHEEL_RADIUS
from wholebody.push.scenes import pushing_scene
from wholebody.viz import Scene
from wholebody.viz.browser import dump_dom, find_chromium, screenshot

WIDTH, HEIGHT = 1024, 768
CART_POSE = (0.9, 0.0, 0.0)


MISSING_BROWSER = (
    "browser tests need headless Chromium: install it with "
    "`sudo apt-get install -y --no-install-recommends chromium fonts-dejavu-core` "
    "(`make test` does this itself when run as root or with passwordless sudo)"
)


CHROMIUM = find_chromium()
if CHROMIUM is None:
    if os.environ.get("CARTPUSH_REQUIRE_BROWSER") == "1":
        raise RuntimeError(MISSING_BROWSER + " [CARTPUSH_REQUIRE_BROWSER=1]")
    pytest.skip(MISSING_BROWSER, allow_module_level=True)


def chromium() -> str:
    """Return the path of the Chromium executable found at import."""
    assert CHROMIUM is not None
    return CHROMIUM


def render(html: Path, png: Path, profile: Path, fragment: str = "", budget_ms: int = 4000) -> np.ndarray:
    """Return the RGB screenshot (H, W, 3) of a local page (URL fragment `fragment`) rendered by headless Chromium."""
    screenshot(chromium(), html, png, size=(WIDTH, HEIGHT), fragment=fragment, profile=profile, budget_ms=budget_ms)
    return np.asarray(Image.open(png).convert("RGB"), dtype=float)


def window(img: np.ndarray, uv: np.ndarray, r: int) -> np.ndarray:
    """Return the pixels (k, 3) of the (2r+1)^2 window around pixel uv."""
    u, v = int(round(uv[0])), int(round(uv[1]))
    assert r <= u < WIDTH - r and r <= v < HEIGHT - r, f"projected point {uv} is off screen"
    return img[v - r : v + r + 1, u - r : u + r + 1].reshape(-1, 3)


def is_yellow(p):
    return (p[:, 0] > 150) & (p[:, 1] > 120) & (p[:, 2] < 90)


def is_orange(p):
    return (p[:, 0] > 150) & (p[:, 1] > 50) & (p[:, 1] < 150) & (p[:, 2] < 70)


def is_red(p):
    return (p[:, 0] > 100) & (p[:, 1] < 60) & (p[:, 2] < 60)


def is_grey(p):
    return (p[:, 0] > 140) & (np.abs(p[:, 2] - p[:, 0]) < 40) & (np.abs(p[:, 1] - p[:, 0]) < 40)


@pytest.fixture(scope="module")
def shots(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("browser")
    with pushing_scene(CART_POSE) as scene:
        camera = scene.camera
        arm_elbow = scene.frame_position("ridgeback_iiwa", "iiwa_link_4")
        scene.save_html(tmp / "scene.html", controls=False)
    with Scene([], camera=camera) as empty:
        empty.save_html(tmp / "empty.html", controls=False)
    img = render(tmp / "scene.html", tmp / "scene.png", tmp / "profile")
    ref = render(tmp / "empty.html", tmp / "empty.png", tmp / "profile")
    x, y, _ = CART_POSE
    points = {
        "ridgeback": (
            np.array([0.0, -0.39, 0.12]),
            is_yellow,
            6,
        ),  # -y face of the chassis (base 0.1 m ahead of the origin)
        "iiwa": (arm_elbow, is_orange, 5),
        "handle": (np.array([x + CART_HANDLE_X, y - 0.2, CART_WHEEL_RADIUS + CART_HANDLE_Z_B]), is_red, 2),
        "basket": (np.array([x + 0.4, y - 0.26, CART_WHEEL_RADIUS + 0.62]), is_grey, 6),  # its -y face
    }
    uv = {k: camera.project(p, WIDTH, HEIGHT)[0] for k, (p, _, _) in points.items()}
    return img, ref, points, uv


def test_screenshot_differs_from_empty_scene_where_objects_stand(shots):
    img, ref, points, uv = shots
    assert img.shape == (HEIGHT, WIDTH, 3)
    for name, (_, _, r) in points.items():
        diff = np.abs(window(img, uv[name], r) - window(ref, uv[name], r)).mean()
        assert diff > 40, f"{name}: mean |scene - empty| = {diff:.1f} at pixel {uv[name].round()}"
    # Far from every object the two screenshots agree (same camera, same background).
    corner = np.abs(img[:60, :200] - ref[:60, :200]).mean()
    assert corner < 2.0, f"background differs by {corner:.1f}: the camera or the page differ"


def test_screenshot_shows_object_colours(shots):
    img, ref, points, uv = shots
    for name, (_, colour, r) in points.items():
        here, empty = colour(window(img, uv[name], r)).mean(), colour(window(ref, uv[name], r)).mean()
        assert here > 0.3, f"{name}: only {here:.0%} of the pixels around {uv[name].round()} have its colour"
        assert empty < 0.05, f"{name}: the empty scene already has its colour there ({empty:.0%})"


def test_objects_cover_a_large_part_of_the_image(shots):
    img, ref, _, _ = shots
    changed = (np.abs(img - ref).sum(axis=2) > 60).mean()
    assert 0.05 < changed < 0.6, f"{changed:.0%} of the pixels changed"


# -- the animated page of `cartpush demo` / `push --html` -------------------------------------------------------
DEMO_DURATION = 8.0  # the shortest run `push` accepts
DEMO_SHOTS = ("start", "middle", "end")


def _root_pose(keys: dict, path: str, frame_times: np.ndarray, t: float) -> tuple[np.ndarray, float]:
    """Return (position, yaw) of an animated root node at time t (keys interpolated as three.js does)."""
    pos = np.array([np.interp(t, frame_times, keys[path]["position"][:, j]) for j in range(3)])
    quat = keys[path]["quaternion"]
    yaw = np.unwrap(2 * np.arctan2(quat[:, 2], quat[:, 3]))
    return pos, float(np.interp(t, frame_times, yaw))


@pytest.fixture(scope="module")
def demo_shots(tmp_path_factory):
    """Screenshots of the demo page and of the same page without robot and cart, at start, middle and end."""
    from wholebody.push import PushConfig, build_scene, run_push

    tmp = tmp_path_factory.mktemp("demo")
    result = run_push(PushConfig(trajectory=2, duration=DEMO_DURATION, contact="optimal", estimation=True))
    with build_scene(result) as scene:
        duration = scene.animation_duration()
        times = dict(zip(DEMO_SHOTS, (0.0, duration / 2, duration)))
        cameras = {k: scene.camera_at(t) for k, t in times.items()}
        keys = scene.animation_keys()
        n = len(keys["/meshcat/ridgeback_iiwa"]["position"])
        frame_times = np.linspace(0.0, duration, n)
        scene.save_html(tmp / "demo.html", controls=False)
        for name in ("ridgeback_iiwa", "shopping_cart"):
            scene.viewer[name].set_property("visible", False)
        scene.save_html(tmp / "hidden.html", controls=False)
    shots = {}
    for k, t in times.items():
        img = render(tmp / "demo.html", tmp / f"demo_{k}.png", tmp / "profile", f"#t={t:.3f}")
        ref = render(tmp / "hidden.html", tmp / f"hidden_{k}.png", tmp / "profile", f"#t={t:.3f}")
        base, base_yaw = _root_pose(keys, "/meshcat/ridgeback_iiwa", frame_times, t)
        cart, cart_yaw = _root_pose(keys, "/meshcat/shopping_cart", frame_times, t)
        c, s = np.cos(cart_yaw), np.sin(cart_yaw)
        points = {
            "ridgeback": base + np.array([0.0, 0.0, 0.2]),  # inside the chassis
            "cart basket": cart + np.array([0.4 * c, 0.4 * s, CART_WHEEL_RADIUS + 0.6]),
        }
        uv = {name: cameras[k].project(p, WIDTH, HEIGHT)[0] for name, p in points.items()}
        shots[k] = (img, ref, uv, tmp / f"demo_{k}.png")
    return shots


@pytest.mark.parametrize("when", DEMO_SHOTS)
def test_demo_page_shows_robot_and_cart_at_start_middle_and_end(demo_shots, when):
    img, ref, uv, _ = demo_shots[when]
    assert img.shape == (HEIGHT, WIDTH, 3)
    for name, p in uv.items():
        assert 80 <= p[0] < WIDTH - 80 and 80 <= p[1] < HEIGHT - 80, (
            f"{when}: {name} projects off screen to {p.round()}"
        )
        diff = np.abs(window(img, p, 6) - window(ref, p, 6)).mean()
        assert diff > 40, f"{when}: {name}: mean |page - page without robots| = {diff:.1f} at pixel {p.round()}"
    changed = (np.abs(img - ref).sum(axis=2) > 60).mean()
    assert 0.05 < changed < 0.6, f"{when}: robot and cart cover {changed:.0%} of the page"
    assert is_yellow(img.reshape(-1, 3)).mean() > 0.004, f"{when}: no Ridgeback yellow on the page"
    assert is_orange(img.reshape(-1, 3)).mean() > 0.002, f"{when}: no iiwa orange on the page"


def is_arrow_blue(p):
    """The applied-force arrow's blue (0x1565C0 under the scene's lights), not the sky behind it."""
    return (p[:, 2] > 110) & (p[:, 0] < 70) & (p[:, 1] > 50) & (p[:, 1] < 150) & (p[:, 2] - p[:, 1] > 60)


@pytest.fixture(scope="module")
def ten_newton_shot(tmp_path_factory):
    """The demo page at the frame whose hand force is nearest 10 N, and the same page without the arrow."""
    from wholebody.push import PushConfig, build_scene, run_push
    from wholebody.viz.scene import ARROW_HEAD

    tmp = tmp_path_factory.mktemp("arrow")
    result = run_push(PushConfig(trajectory=2, duration=DEMO_DURATION, contact="optimal", estimation=True))
    with build_scene(result) as scene:
        keys = scene.animation_keys()["/meshcat/wrenches/applied/hand"]
        shaft = scene.animation_keys()["/meshcat/wrenches/applied/hand/shaft"]["scale"][:, 0]
        head = scene.animation_keys()["/meshcat/wrenches/applied/hand/head"]["scale"][:, 0] * ARROW_HEAD
        length = shaft + head
        k = int(np.argmin(np.abs(length / scene.arrow_scale - 10.0)))
        force, t = length[k] / scene.arrow_scale, k / 10.0  # build_scene animates at 10 frames per second
        x, y, z, w = keys["quaternion"][k]
        direction = np.array([1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w)])
        points = keys["position"][k] + np.outer([0.25, 0.5, 0.75], length[k] * direction)
        uv = scene.camera_at(t).project(points, WIDTH, HEIGHT)
        scene.save_html(tmp / "page.html", controls=False)
        scene.viewer["wrenches"].set_property("visible", False)
        scene.save_html(tmp / "no_arrow.html", controls=False)
    img = render(tmp / "page.html", tmp / "page.png", tmp / "profile", f"#t={t:.3f}")
    ref = render(tmp / "no_arrow.html", tmp / "no_arrow.png", tmp / "profile", f"#t={t:.3f}")
    return img, ref, uv, force, length[k]


def test_ten_newton_hand_force_is_a_visible_arrow(ten_newton_shot):
    img, ref, uv, force, length = ten_newton_shot
    assert abs(force - 10.0) < 1.5, f"no frame near 10 N (nearest {force:.1f} N)"
    assert length > 0.3, f"a {force:.1f} N arrow is only {100 * length:.0f} cm long"
    arrow = is_arrow_blue(img.reshape(-1, 3)) & ~is_arrow_blue(ref.reshape(-1, 3))
    assert arrow.sum() > 300, f"only {arrow.sum()} arrow-blue pixels for a {force:.1f} N hand force"
    for p in uv:  # along the arrow (a quarter, half, three quarters of its length) the page is arrow blue
        here = is_arrow_blue(window(img, p, 3)).mean()
        assert here > 0.2, f"{here:.0%} arrow blue at {p.round()} ({force:.1f} N arrow, {100 * length:.0f} cm)"


# -- every kind of animated page, opened as a user opens it ---------------------------------------------------------
PAGES = ("push", "scenario", "log")


@pytest.fixture(scope="module")
def cli_pages(tmp_path_factory):
    """The pages `cartpush push --html`, `view --scenario 6 --html` and `view LOG --html` write."""
    from cartpush.cli import main

    tmp = tmp_path_factory.mktemp("pages")
    pages = {name: tmp / f"{name}.html" for name in PAGES}
    # 16-20 s animations: the pages loop, and the two moments compared (up to ~10 s apart) must not wrap round
    assert main(["push", "--duration", "16", "--html", str(pages["push"]), "--out", str(tmp / "run")]) == 0
    assert main(["view", "--scenario", "6", "--duration", "20", "--html", str(pages["scenario"])]) == 0
    assert main(["view", str(tmp / "run" / "push_log.csv"), "--html", str(pages["log"])]) == 0
    return pages


def _clock(dom: str) -> tuple[str, float]:
    """Return (button text, animation time in s) of a page's DOM."""
    import re

    button = re.search(r'id="cartpush-play"[^>]*>([^<]*)<', dom).group(1)
    t = float(re.search(r'id="cartpush-time"[^>]*>t = ([0-9.]+) /', dom).group(1))
    return button, t


@pytest.mark.parametrize("kind", PAGES)
def test_page_plays_when_opened_without_fragment(cli_pages, kind):
    """Opened as a user opens it (real time, no fragment), the page plays: its clock runs and the picture changes."""
    import io

    from wholebody.viz.browser import DevToolsPage

    with DevToolsPage(chromium(), cli_pages[kind], size=(WIDTH, HEIGHT)) as page:
        t0 = _wait_for(page, f"{CLOCK} > 0.5 && {CLOCK}")
        assert "pause" in page.evaluate(BUTTON), f"{kind}: the button does not offer pause: not playing"
        early = page.screenshot()
        t1 = _wait_for(page, f"Math.abs({CLOCK} - {t0}) > 2 && {CLOCK}")  # later (or wrapped round the loop)
        late = page.screenshot()
    early, late = (np.asarray(Image.open(io.BytesIO(b)).convert("RGB"), dtype=float) for b in (early, late))
    changed = (np.abs(early - late).sum(axis=2) > 30).mean()
    assert changed > 0.01, f"{kind}: {changed:.2%} of the pixels changed from t = {t0} s to {t1} s: it stands still"


@pytest.mark.parametrize("kind", PAGES)
def test_paused_page_stands_still(cli_pages, kind, tmp_path):
    html = cli_pages[kind]
    early = render(html, tmp_path / "early.png", tmp_path / "profile", "#pause", budget_ms=1500)
    late = render(html, tmp_path / "late.png", tmp_path / "profile", "#pause", budget_ms=6000)
    assert np.abs(early - late).mean() < 0.5, f"{kind}: a paused page moved"
    button, t = _clock(dump_dom(chromium(), html, "#pause", budget_ms=3000))
    assert "play" in button and t == 0.0


def _wait_for(page, expression: str, timeout: float = 60.0) -> object:
    """Poll a JavaScript expression until it is truthy (the browser runs in real time); return its value."""
    import time

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = page.evaluate(expression)
        if value:
            return value
        time.sleep(0.2)
    raise AssertionError(f"{expression} stayed false for {timeout:g} s")


CLOCK = "parseFloat(((document.getElementById('cartpush-time') || {}).textContent || 't = 0').split(' ')[2])"
BUTTON = "document.getElementById('cartpush-play').textContent"


def test_pause_button_and_space_bar_stop_and_resume_the_page(cli_pages):
    """A user's click on the pause button stops the page; the space bar resumes it (DevTools mouse and key events)."""
    import time

    from wholebody.viz.browser import DevToolsPage

    with DevToolsPage(chromium(), cli_pages["push"]) as page:
        _wait_for(page, f"{CLOCK} > 0.5")  # it plays by itself
        assert "pause" in page.evaluate(BUTTON)
        page.click("cartpush-play")
        assert "play" in page.evaluate(BUTTON)
        paused_at = page.evaluate(CLOCK)
        time.sleep(1.0)
        assert page.evaluate(CLOCK) == paused_at, "the clock moved while paused"
        page.press(" ", "Space")
        _wait_for(page, f"{CLOCK} > {paused_at} + 0.3")
        assert "pause" in page.evaluate(BUTTON)


OVERLAY = (
    "(function () { const r = document.getElementById('cartpush-overlay').getBoundingClientRect();"
    " const c = document.getElementById('cartpush-charts-panel');"
    " return {w: r.width, h: r.height, legend: document.getElementById('cartpush-legend').open, charts: c.open}; })()"
)


def test_the_overlay_leaves_the_scene_free_in_a_1024_x_768_window(cli_pages):
    """In a 1024 x 768 window the push page's overlay is the player and the read-outs in a strip of the bottom-left
    corner: its legend opens folded (a click opens it); in a large window it opens open. The charts fold too."""
    from wholebody.viz.browser import DevToolsPage
    from wholebody.viz.page import LEGEND_FOLD_SHARE

    with DevToolsPage(chromium(), cli_pages["push"], size=(WIDTH, HEIGHT)) as page:
        _wait_for(page, f"{CLOCK} > 0.1")
        box = page.evaluate(OVERLAY)
        assert box["legend"] is False and box["charts"] is True
        assert box["h"] <= LEGEND_FOLD_SHARE * HEIGHT and box["w"] <= 0.45 * WIDTH, box
        assert box["w"] * box["h"] < 0.08 * WIDTH * HEIGHT, f"the overlay covers {box} of a {WIDTH} x {HEIGHT} window"
        page.click("cartpush-legend-toggle")
        page.click("cartpush-charts-toggle")
        box = page.evaluate(OVERLAY)
        assert box["legend"] is True and box["charts"] is False
    with DevToolsPage(chromium(), cli_pages["push"], size=(1920, 1200)) as page:
        _wait_for(page, f"{CLOCK} > 0.1")
        assert page.evaluate(OVERLAY)["legend"] is True


def test_notebook_iframe_inflates_and_renders_the_scene(tmp_path):
    """`Scene.iframe()` (gzipped page in srcdoc, as notebooks show it) renders the robot and the cart in a browser."""
    with pushing_scene(CART_POSE) as scene:
        frame = scene.iframe(height=600)
    page = tmp_path / "notebook.html"
    page.write_text(f"<!DOCTYPE html><html><body style='margin: 0'>{frame}</body></html>", encoding="utf-8")
    img = render(page, tmp_path / "notebook.png", tmp_path / "profile").reshape(-1, 3)
    assert is_yellow(img).mean() > 0.004 and is_orange(img).mean() > 0.002, "no Ridgeback / iiwa in the iframe"
    assert is_grey(img).mean() > 0.02, "no cart basket in the iframe"
