"""The load-change test beds count a log ``estimate`` refuses instead of stopping on it.

``estimate`` refuses some logs outright (a wrench zero throughout, a torque about the world origin: a
:class:`cart.errors.CartError`); the test beds' evaluation (``mujoco_loads.evaluate``,
``log_recorders.load_change_study``) must report such a log as refused, one segment without a mass, and go on.
"""

from __future__ import annotations

import numpy as np

from cart.estimate_report import estimate_log
from cart.logs import CartLog
from studies.testbeds import rigid_sim
from studies.testbeds.mujoco_loads import estimated_segments


def test_a_refused_log_gives_one_segment_without_a_mass_and_the_message():
    t = np.arange(4000) / 100.0
    q = np.column_stack([0.3 * t, 0.1 * np.sin(0.2 * t), 0.05 * np.sin(0.3 * t)])
    q = q + np.random.default_rng(60103).normal(0.0, 5e-4, q.shape)
    segs = estimated_segments(CartLog(t=t, q=q, gamma=np.zeros((len(t), 3))))
    assert len(segs) == 1
    assert segs[0]["mass"] is None and segs[0]["t0_range"] is None
    assert "the wrench is zero throughout" in segs[0]["refused"]


def test_a_log_estimate_takes_gives_its_segments():
    log, truth = rigid_sim.simulate(rigid_sim.random_case(3001, duration=30.0))
    segs = estimated_segments(log)
    want = list(estimate_log(log).segments)
    assert [s["mass"] for s in segs] == [s["mass"] for s in want]
    assert "refused" not in segs[-1]
    assert abs(segs[-1]["mass"] / truth["m"] - 1.0) < 0.1
