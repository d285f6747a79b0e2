"""A run whose hand leaves the handle says so (wholebody.push.report.what_happened's second sentence)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from wholebody.push.report import HAND_OFF_HANDLE_M, _hand_off_handle


def _result(err: np.ndarray, dt: float = 0.01) -> SimpleNamespace:
    return SimpleNamespace(t=dt * np.arange(err.shape[0]), grasp_error=err, config=SimpleNamespace(dt=dt))


def test_a_hand_off_the_handle_is_reported_with_when_how_long_and_how_far():
    err = np.full((1000, 2), 0.001)
    err[400:520, 1] = 0.16 * np.sin(np.linspace(0.0, math.pi, 120))  # hand 2 swings 160 mm off from 4 s
    lines = _hand_off_handle(_result(err), math.inf)
    assert len(lines) == 1 and lines[0].startswith("HAND OFF THE HANDLE: hand 2")
    off = int(np.sum(err[:, 1] > HAND_OFF_HANDLE_M))
    assert f"for {0.01 * off:.2f} s" in lines[0] and "at most 160 mm" in lines[0]
    assert f"from t = {0.01 * int(np.argmax(err[:, 1] > HAND_OFF_HANDLE_M)):.2f} s" in lines[0]


def test_a_hand_on_the_handle_or_off_only_after_the_loss_says_nothing():
    err = np.full((1000, 1), 0.001)
    assert _hand_off_handle(_result(err), math.inf) == []
    err[800:, 0] = 0.3  # after the cart was lost at 7 s: a failed push, not an arm that could not follow
    assert _hand_off_handle(_result(err), 7.0) == []
    assert "the hand was" in _hand_off_handle(_result(err), math.inf)[0]
