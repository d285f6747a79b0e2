"""Issue 14, class 7: `view` must not hang on logs in map coordinates, millimetres or long time spans."""

from __future__ import annotations

import time

import numpy as np

from cart.logs import CartLog, write_log
from cartpush.cli import main
from wholebody.viz import MAX_FLOOR_LINES, MAX_FRAMES, Scene, log_scene


def test_floor_grid_is_sized_to_the_data():
    with Scene(["shopping_cart"]) as sc:
        assert sc.set_floor((-2.0, 6.0, -3.0, 3.0)) == 13 * 16 + 17 * 12  # 0.5 m cells as before
        n = sc.set_floor((500_000.0, 527_000.0, 4_000_000.0, 4_002_000.0))  # map coordinates, 27 km
        assert n <= 2 * MAX_FLOOR_LINES**2


def test_long_log_in_millimetres_is_capped_and_fast(tmp_path):
    t = np.arange(0.0, 30_000.0, 1.0)  # 8 h 20 min at 1 Hz: 900,000 frames at 30 fps uncapped
    q = np.column_stack([500.0 * np.sin(t / 3000.0), 500.0 * t / 30.0, 0.01 * t])  # millimetre-sized numbers
    g = np.column_stack([10 + 0 * t, 0 * t, 0 * t])
    path = tmp_path / "long_mm.csv"
    write_log(path, CartLog(t=t, q=q, gamma=g))
    t0 = time.perf_counter()
    with log_scene(str(path)) as scene:
        keys = scene.animation_keys()
    assert time.perf_counter() - t0 < 60.0
    n_keys = max(len(v["position"]) for v in keys.values() if "position" in v)
    assert n_keys <= MAX_FRAMES
    out = tmp_path / "page.html"
    assert main(["view", str(path), "--html", str(out)]) == 0
    assert out.stat().st_size < 50e6
