"""The online estimator's wrench noise in the push loop: one sensor's for one hand, the sum's for several."""

from __future__ import annotations

import math

import numpy as np

from wholebody.push.config import PushConfig
from wholebody.push.loop import make_estimator, summed_wrench_std


def test_one_hand_is_its_sensor():
    cfg = PushConfig(trajectory=1)
    assert summed_wrench_std(cfg) == (cfg.noise.force, cfg.noise.torque)


def test_two_hands_add_their_noise_and_its_lever_arms():
    """Two hands at the handle's (x, +-0.2) in {b}: the force noise sqrt(2) times a sensor's, the torque's with each
    hand's force noise times its lever arm."""
    cfg = PushConfig(trajectory=1, n_arms=2)
    sf, st = cfg.noise.force, cfg.noise.torque
    x = float(cfg.cart_geometry().point(0.2)[0])
    f, t = summed_wrench_std(cfg)
    assert math.isclose(f, math.sqrt(2.0) * sf)
    assert math.isclose(t, math.sqrt(2.0 * (st * st + (x * x + 0.04) * sf * sf)))
    est = make_estimator(cfg, np.zeros(3))
    assert est.options.wrench_std == (f, t)  # type: ignore[attr-defined]
