"""The page of a push by two robots side by side draws both, each hand's force arrow at its own contact.

It drew robot 1 and hand 1 only (an outside look at `--arms 2` pages: the second grip held by nobody), while
docs/viz.md said each hand's force is drawn. Checked on the scene's animation (no browser): both robots' roots
move along their own bases' recorded paths, and the arrows start at their hands' handle points.
"""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture(scope="module")
def two_robot_run():
    from wholebody.push import PushConfig, run_push

    return run_push(PushConfig(n_arms=2, trajectory=1, duration=3.0))


def test_both_robots_and_both_hands_are_drawn(two_robot_run):
    from wholebody.push import build_scene

    result = two_robot_run
    with build_scene(result, fps=5) as scene:
        assert set(scene.robots) == {"ridgeback_iiwa", "ridgeback_iiwa_2", "shopping_cart"}
        keys = scene.animation_keys()
        for k, name in enumerate(("ridgeback_iiwa", "ridgeback_iiwa_2")):
            xy = np.asarray(keys[f"/meshcat/{name}"]["position"])[:, :2]
            assert xy[0] == pytest.approx(result.robot_x[0, k, :2], abs=1e-6)
        starts = [np.asarray(keys[f"/meshcat/wrenches/applied/{h}"]["position"])[0] for h in ("hand", "hand2")]
        assert np.linalg.norm(starts[0][:2] - starts[1][:2]) == pytest.approx(
            abs(result.contact_y[0, 1] - result.contact_y[0, 0]), abs=0.02
        )


def test_one_base_holding_both_hands_is_drawn_once():
    from types import SimpleNamespace

    from pathlib import Path

    import robots
    from wholebody.push.report import _drawn_robots

    profile = str(Path(__file__).resolve().parents[2] / "robots" / "examples" / "tiago_dual.toml")
    loaded = robots.load(profile)  # TIAGo++: two arms on one base
    run = SimpleNamespace(config=SimpleNamespace(robot=profile), robot_x=np.zeros((3, 2, 10)))
    assert list(_drawn_robots(run, loaded)) == [profile]
    one = SimpleNamespace(config=SimpleNamespace(robot="wmra"), robot_x=np.zeros((3, 2, 10)))
    assert list(_drawn_robots(one, robots.load("wmra"))) == ["wmra", "wmra_2"]
