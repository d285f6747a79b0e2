"""Tests of the online estimator under model misfit (issue 27): a residual change that is no load change."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from cart.change_detection import ChangeDetector
from cart.online_estimator import OnlineLSEstimator, make_online_estimator
from tests.cart.test_online_estimator import GUESS, MOCAP, TRUTH, _run, _sim


def _with_yaw_friction(log, t0: float, t1: float, torque: float):
    """Return a copy of the log whose measured torque carries a Coulomb yaw friction between t0 and t1.

    The model has none (a real cart's casters scrub when they swivel): the regression's torque row misfits
    while the cart's mass stays the same.
    """
    bad = log.gamma.copy()
    on = (log.t > t0) & (log.t < t1)
    bad[on, 2] -= torque * np.tanh(log.qd[on, 2] / 0.05)
    return replace(log, gamma=bad)


@pytest.fixture(scope="module")
def misfit_log():
    """The turning pushes of a 20 kg cart whose casters resist turning with 4 N m (the residual ratio goes to ~4)."""
    return _with_yaw_friction(_sim(30.0, True).measured, 0.0, 30.0, 4.0)


def test_a_misfit_is_no_load_change(misfit_log):
    """The residual test flags the misfit; no load change is reported and the mass stays within 1.5 kg."""
    est = _run(misfit_log, make_online_estimator(misfit_log.q[0], GUESS, MOCAP.measurement_std()), 1, 3.0, 0.3)
    kinds = [f.kind for f in est.flags]
    assert est.events == ()
    assert "misfit" in kinds
    assert abs(est.params().m - TRUTH.m) < 1.5


def _glr_without_misfit(monkeypatch) -> None:
    """Make the GLR test ignore the model's residual ratio (its chi-square as if the model fitted)."""
    update = ChangeDetector.update
    monkeypatch.setattr(ChangeDetector, "update", lambda self, *a: update(self, *a[:6], misfit=1.0))


def test_the_glr_scaled_by_the_misfit_does_not_fire_on_it(misfit_log, monkeypatch):
    """Every GLR detection accepted (no confirmation): the test whose score covariance is scaled by the squared
    residual ratio reports no load change on the misfit's residuals."""
    monkeypatch.setattr(OnlineLSEstimator, "_confirmed", lambda self, new, before, misfit: True)
    est = _run(misfit_log, make_online_estimator(misfit_log.q[0], GUESS, MOCAP.measurement_std()), 1, 3.0, 0.3)
    assert est.events == ()


def test_the_confirmation_rejects_what_the_unscaled_glr_finds(misfit_log, monkeypatch):
    """The GLR as if the model fitted fires on the misfit; the two sides of each onset do not confirm a mass
    change: every detection is flagged and none is reported. Accepting every detection too resets (load changes
    reported: what the two tests above rule out)."""
    _glr_without_misfit(monkeypatch)
    est = _run(misfit_log, make_online_estimator(misfit_log.q[0], GUESS, MOCAP.measurement_std()), 1, 3.0, 0.3)
    assert est.events == ()
    assert "change_not_confirmed" in [f.kind for f in est.flags]
    monkeypatch.setattr(OnlineLSEstimator, "_confirmed", lambda self, new, before, misfit: True)
    est = _run(misfit_log, make_online_estimator(misfit_log.q[0], GUESS, MOCAP.measurement_std()), 1, 3.0, 0.3)
    assert len(est.events) >= 1


def test_the_detector_scales_its_chi_square_by_the_misfit():
    """Residuals three times the noise model's, no change: the unscaled GLR passes its threshold, scaled by 3^2 it
    does not."""
    fired = {1.0: False, 3.0: False}
    for misfit in fired:
        det = ChangeDetector(window_s=1.5, alpha=1e-6, min_change=0.0)
        local = np.random.default_rng(1)
        for _ in range(600):
            phi = local.standard_normal((2, 4))
            r = 3.0 * local.standard_normal(2)
            fired[misfit] |= det.update(0.01, phi.T @ r, phi.T @ phi, np.zeros((4, 4)), np.eye(4), 20.0, misfit)
    assert fired == {1.0: True, 3.0: False}


@pytest.mark.parametrize("deflate", [True, False])
def test_the_com_given_to_the_controller_is_no_worse_than_the_prior_under_misfit(deflate):
    """Pushes with little turning and a caster yaw friction the model lacks: the regression's CoM runs off (25 cm
    from the truth, the guess is 15 cm off); the CoM the controller gets, its pull from the prior deflated by the
    misfit, stays within the guess's error. Without the deflation it does not (the same run, ``deflate_com``).
    The regression's samples at the noise model's weights (``misfit_weights=False``): the deflation alone."""
    log = _with_yaw_friction(_sim(30.0, False).measured, 0.0, 30.0, 4.0)
    est = make_online_estimator(log.q[0], GUESS, MOCAP.measurement_std(), deflate_com=deflate, misfit_weights=False)
    p = _run(log, est, 1, 3.0, 0.3).params()
    error, prior_error = (
        math.hypot(p.dx - TRUTH.dx, p.dy - TRUTH.dy),
        math.hypot(GUESS.dx - TRUTH.dx, GUESS.dy - TRUTH.dy),
    )
    raw = est.regression.p
    assert math.hypot(raw[1] / raw[0] - TRUTH.dx, raw[2] / raw[0] - TRUTH.dy) > prior_error
    assert (error <= prior_error) == deflate
    assert abs(p.m - TRUTH.m) < 1.5


def test_misfit_weights_bring_the_com_nearer_and_widen_the_mass_std():
    """The same pushes and caster yaw friction, the CoM deflated as by default: with each sample weighted by the
    model's residual ratio (default) the CoM given to the controller ends within a third of the guess's error and
    at most half as far as at the noise model's weights (``misfit_weights=False``); the mass std widens with the
    misfit and covers the mass's error twice over."""
    log = _with_yaw_friction(_sim(30.0, False).measured, 0.0, 30.0, 4.0)
    errors, stds = {}, {}
    for weights in (True, False):
        est = make_online_estimator(log.q[0], GUESS, MOCAP.measurement_std(), misfit_weights=weights)
        p = _run(log, est, 1, 3.0, 0.3).params()
        errors[weights] = math.hypot(p.dx - TRUTH.dx, p.dy - TRUTH.dy)
        stds[weights] = est.params_std()["mass"]
        assert abs(p.m - TRUTH.m) < 2.0 * stds[weights]
    prior_error = math.hypot(GUESS.dx - TRUTH.dx, GUESS.dy - TRUTH.dy)
    assert errors[True] <= prior_error / 3.0 and errors[True] <= 0.5 * errors[False]
    assert stds[True] > stds[False]
