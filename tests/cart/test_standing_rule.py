"""One standing rule (:mod:`cart.standing`) for the estimate and the diagnosis.

The estimate (:func:`cart.identify._noise_levels`) and the diagnosis (:func:`cart.diagnose._stands`)
refuse a cart whose pose does not move beyond its noise by the same predicate and constant; raising the
constant makes both refuse a log that moves (each read its own copy of the 20 stds before).
"""

from __future__ import annotations

import numpy as np
import pytest

import cart.standing
from cart.diagnose import diagnose
from cart.errors import DiagnoseError
from cart.identify import IdentifiabilityError, identify
from cart.standing import STAND_SPAN_STDS, pose_stands
from studies.testbeds import rigid_sim


def _pose(span_stds: float, heading_stds: float, std: float = 1e-3, theta_std: float = 2e-3) -> np.ndarray:
    q = np.zeros((200, 3))
    q[:, 0] = np.linspace(0.0, span_stds * std, 200)
    q[:, 2] = np.linspace(0.0, heading_stds * theta_std, 200)
    return q


def test_the_predicate_counts_noise_stds_of_the_positions_and_of_the_heading():
    below, above = 0.9 * STAND_SPAN_STDS, 1.1 * STAND_SPAN_STDS
    assert pose_stands(_pose(below, 0.0), 1e-3)
    assert not pose_stands(_pose(above, 0.0), 1e-3)
    # the heading is checked only where its noise is given (the diagnosis); a turn in place moves
    assert pose_stands(_pose(below, above), 1e-3)
    assert not pose_stands(_pose(below, above), 1e-3, 2e-3)
    assert pose_stands(_pose(below, below), 1e-3, 2e-3)


def test_estimate_and_diagnose_read_the_same_constant(monkeypatch):
    log, _ = rigid_sim.simulate(rigid_sim.random_case(61010, duration=15.0))
    span = float(np.max(np.ptp(log.q[:, :2], axis=0)))
    # the log moves: far beyond 20 stds of its millimetre noise
    monkeypatch.setattr(cart.standing, "STAND_SPAN_STDS", 1e3 * span / 1e-3)
    with pytest.raises(IdentifiabilityError, match="does not move beyond the pose noise"):
        identify(log)
    with pytest.raises(DiagnoseError, match="does not move beyond the noise"):
        diagnose(log)
