"""Issue 30: a torque taken about the world origin instead of {b}'s origin is refused by `estimate` with the fix.

rigid_sim seed 19 with tau + x fy - y fx written as the torque: `estimate` answered the mass with exit 0, the
model not fitting (the yaw residual 13x the noise) and a CoM std of half a metre; moved back to {b}, about 1x.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cart.estimate_report import estimate_log
from cart.units import UnitsError, check_torque_origin
from studies.testbeds import rigid_sim


def _about_world_origin(log):
    g = log.gamma
    tau = g[:, 2] + log.q[:, 0] * g[:, 1] - log.q[:, 1] * g[:, 0]
    return replace(log, gamma=np.column_stack([g[:, 0], g[:, 1], tau]))


def test_a_torque_about_the_world_origin_is_refused_with_the_moment_named():
    log, truth = rigid_sim.simulate(rigid_sim.random_case(19, duration=40.0, rate_hz=100.0))
    ok = estimate_log(log)
    assert ok.model_fits and abs(ok.params.m / truth["m"] - 1) < 0.02
    with pytest.raises(UnitsError, match=r"world origin.*tau - \(x fy - y fx\)"):
        estimate_log(_about_world_origin(log))


def test_the_check_needs_the_yaw_residual_to_drop_and_skips_a_fitting_model():
    check_torque_origin("log", (1.0, 3.0), None)  # the model fits: not checked
    check_torque_origin("log", (1.0, 3.0), 2.5)  # a misfit the origin does not explain
    check_torque_origin("log", (1.0, 3.0), float("nan"))
    with pytest.raises(UnitsError, match="world origin"):
        check_torque_origin("log", (1.0, 3.0), 1.0)
