"""Issue 30 audit (fresh seeds): two logs `diagnose` answered with exit 0 and a wrong report.

- A cart standing still (pose noise 0.1 mm / 0.1 mrad, a random wrench): the extreme speeds of ~6000
  differentiated noise samples passed the 5-std speed test, and the bounded nominal fit named `caster_swivel`
  (a 14 kN m torque) and `payload_change` (CoM 12 m behind the axle). `estimate` refuses it (the positions span
  no more than 20 noise stds); `diagnose` now too.
- A rigid_sim push (seed 60100) with its wrench's sign flipped: read in {b} it does +2.0 J of work against
  -36.4 J as logged, so the rule "negative work in both frames" let it through to the bounded fit, which named
  nothing ("the nominal model explains the log", replay gap 1254 mm over a 64 mm noise floor). A {b} reading
  that shows no clearer push than the logged one shows a pull is no frame problem: refused with the sign named,
  by `diagnose` and by `estimate`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cart.diagnose import diagnose
from cart.errors import CartError, DiagnoseError
from cart.estimate_report import estimate_log
from cart.logs import CartLog
from studies.testbeds import rigid_sim


def _standing_log() -> CartLog:
    t = np.arange(5921) / 148.0
    rng = np.random.default_rng(60101)
    q = np.array([1.0, -0.5, 0.3]) + rng.normal(0.0, 1e-4, (len(t), 3))
    return CartLog(t=t, q=q, gamma=np.random.default_rng(60102).normal(0.0, 1.0, (len(t), 3)))


def test_a_standing_cart_is_not_diagnosed():
    log = _standing_log()
    with pytest.raises(DiagnoseError, match="does not move beyond the noise"):
        diagnose(log)
    with pytest.raises(CartError, match="does not move beyond the pose noise"):
        estimate_log(log)


@pytest.fixture(scope="module")
def flipped_log() -> CartLog:
    log, _ = rigid_sim.simulate(rigid_sim.random_case(60100, duration=40.0))
    return replace(log, gamma=-log.gamma)


def test_a_flipped_wrench_is_refused_by_diagnose(flipped_log):
    with pytest.raises(DiagnoseError, match="sign looks flipped"):
        diagnose(flipped_log)


def test_a_flipped_wrench_is_named_by_estimate(flipped_log):
    with pytest.raises(CartError, match="sign looks flipped"):
        estimate_log(flipped_log)
