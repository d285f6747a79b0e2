"""Issue 30, glitches: a motion-capture heading sample flipped by about pi (a quaternion's sign, a marker swap).

``np.unwrap`` read the flip and its return with one sign when the noise on them fell that way, leaving the rest of
the log pi or 2 pi off: the cart seemed to move backwards (an independent simulator's 25.5 kg cart read as not
identified, std 47 kg). `cart.heading.unwrap_heading` makes the heading after the excursion continue the
heading before it; the flipped samples stay spikes that `cart.streams` drops.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cart.estimate_report import estimate_log
from cart.heading import unwrap_heading
from cart.logs import CartLog, write_log
from tests.cart.test_streams_jumps import _push


def _wrapped(a: np.ndarray) -> np.ndarray:
    return (a + math.pi) % (2 * math.pi) - math.pi


@pytest.mark.parametrize("eps", [-0.01, 0.01])
@pytest.mark.parametrize("held", [1, 4])
def test_a_flip_and_its_return_leave_the_heading_after_it_where_it_was(eps, held):
    t = np.arange(0.0, 20.0, 0.01)
    truth = 0.4 * t  # turns past +-pi: the log wraps
    raw = _wrapped(truth)
    flip = slice(1000, 1000 + held)
    raw[flip] = _wrapped(raw[flip] + math.pi + eps)
    raw[1000 + held] += 3 * eps  # noise on the return: numpy reads the flip and the return with one sign
    got = unwrap_heading(t, raw)
    away = np.ones(len(t), bool)
    away[flip] = away[1000 + held] = False  # the return sample carries its own 3 eps of noise
    assert np.allclose(got[away] - truth[away], got[0] - truth[0], atol=2e-3)
    assert np.all(np.abs(np.abs(got[flip] - truth[flip]) - math.pi) < 0.02)  # a spike of pi, not a step


def test_a_heading_that_jumps_and_stays_is_unwrapped_as_numpy_does():
    t = np.arange(0.0, 20.0, 0.01)
    raw = _wrapped(0.1 * t)
    raw[1000:] = _wrapped(raw[1000:] + 2.0)  # a re-registration: the heading stays 2 rad off
    assert np.allclose(unwrap_heading(t, raw), np.unwrap(raw))
    assert np.allclose(unwrap_heading(t, _wrapped(3.0 * t)), np.unwrap(_wrapped(3.0 * t)))


@pytest.mark.parametrize("eps", [-0.01, 0.01])
def test_one_flipped_heading_costs_the_mass_nothing(eps, tmp_path):
    log, truth = _push()
    q = log.q.copy()
    q[1500, 2] += math.pi + eps
    q[1501, 2] += 3 * eps  # noise on the return: numpy reads the flip and the return with one sign
    path = tmp_path / "flip.csv"
    write_log(path, CartLog(t=log.t, q=q, gamma=log.gamma), wrap_theta=True)
    clean, flipped = estimate_log(log), estimate_log(str(path))
    assert flipped.params.m == pytest.approx(clean.params.m, rel=0.01)
    assert flipped.params.m == pytest.approx(truth, rel=0.05) and flipped.model_fits
