"""When a cart stands: one rule for the estimate (:mod:`cart.identify`) and the diagnosis (:mod:`cart.diagnose`).

A standing cart's pose does not wander beyond a few of its noise stds, however long the log; the
extreme speeds of thousands of differentiated noise samples do (past 5 of their std), so the rule is on
the pose's span, not on the speeds.
"""

from __future__ import annotations

import numpy as np

#: a pose that spans at most this many noise stds (positions; heading, where checked) has not moved
STAND_SPAN_STDS = 20.0


def pose_stands(q: np.ndarray, pos_std: float, theta_std: float | None = None) -> bool:
    """Return True when the pose ``q`` (N, 3: x, y, theta) does not move beyond its noise.

    The positions span at most :data:`STAND_SPAN_STDS` pose-noise stds ``pos_std`` (the larger span
    of x and y) and, when ``theta_std`` is given, the heading at most as many heading-noise stds.
    """
    q = np.asarray(q, float)
    span = float(np.max(np.ptp(q[:, :2], axis=0)))
    if span > STAND_SPAN_STDS * pos_std:
        return False
    return theta_std is None or float(np.ptp(q[:, 2])) <= STAND_SPAN_STDS * theta_std
