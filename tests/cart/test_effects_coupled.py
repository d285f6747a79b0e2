"""Friction and damping judged alike across effects: Coulomb friction's hold at rest, a fit with an anti-damping."""

from __future__ import annotations

import numpy as np

from cart.diagnose import N_NOMINAL, Fit, _damping_ok, _design, _start_fit
from cart.effects import CoulombFriction, nominal_columns
from cart.log_signals import signals_from_log, window_edges
from cart.logs import CartLog


def _cart_at_rest(push: float) -> tuple:
    """Return the signals, nominal rows and phi of a cart standing still for 10 s under a forward push (N)."""
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 10.0, 0.01)
    gamma = np.zeros((len(t), 3))
    gamma[:, 0] = push + rng.normal(0.0, 0.5, len(t))
    sig = signals_from_log(CartLog(t=t, q=np.zeros((len(t), 3)), gamma=gamma))
    return sig, nominal_columns(sig), np.array([20.0, 6.0, 0.0, 4.0])


def test_coulomb_friction_holds_a_push_below_its_force_and_is_at_its_limit_above_it():
    sig, base, phi = _cart_at_rest(6.0)
    cf = CoulombFriction()
    inner = slice(50, -50)
    held = cf.offset(sig, (), phi, base, np.array([10.0, 0.0]))  # F = 10 N holds a 6 N push
    assert held is not None
    np.testing.assert_allclose(held[inner, 0], sig.f_fwd[inner])
    assert np.all(cf.columns(sig, (), phi, base)[inner, 0, 0] == 0.0)
    at_limit = cf.offset(sig, (), phi, base, np.array([5.0, 0.0]))  # F = 5 N: the 6 N push is at the limit
    assert at_limit is None or np.all(at_limit[inner, 0] == 0.0)
    assert np.all(cf.columns(sig, (), phi, base)[inner, 0, 0] == 1.0)  # linear in F there: the push informs F


def test_coulomb_friction_does_not_hold_the_noise_of_a_cart_at_rest():
    sig, base, phi = _cart_at_rest(0.0)
    cf = CoulombFriction()
    held = cf.offset(sig, (), phi, base, np.array([10.0, 0.0]))
    share = 0.0 if held is None else float(np.mean(held[:, 0] != 0.0))
    assert share < 0.1  # a 0.5 N noise is no hold (within 2 stds of its local mean)
    assert np.mean(cf.columns(sig, (), phi, base)[:, 0, 0] != 0.0) < 0.1


def test_the_fit_builds_coulomb_frictions_hold_from_each_new_force_estimate():
    # a 6 N push at rest is held by F = 10 N (column 0) and at the limit of F = 5 N (column 1 there): a fit that
    # kept its first iterate's columns would judge every later estimate of F by the first one's holds
    sig, _, phi = _cart_at_rest(6.0)
    edges = window_edges(sig.t, 2.0 * sig.half_window, sig.breaks)
    st = _start_fit(sig, edges, [(CoulombFriction(), ())], phi, [np.array([10.0, 0.0])], 12)
    held = _design(st, edges)[0][1:-1, 0, N_NOMINAL]
    st.thetas_prev = [np.array([5.0, 0.0])]
    at_limit = _design(st, edges)[0][1:-1, 0, N_NOMINAL]
    np.testing.assert_allclose(held, 0.0, atol=1e-9)
    np.testing.assert_allclose(at_limit, np.diff(sig.t[edges])[1:-1], rtol=1e-6)  # 1 over each inner window


def _fit_with(sigma: float, std: float) -> Fit:
    x = np.array([20.0, 6.0, 0.0, 4.0, sigma, 1.0])
    cov = np.diag([1.0, 1.0, 1.0, 1.0, std**2, 0.01])
    return Fit(effects=[], x=x, thetas=[], rss=np.ones(3), n_win=100, cov=cov, m2ll=0.0, sig=None)


def test_a_significantly_negative_damping_is_no_cart():
    assert _damping_ok(_fit_with(2.0, 1.0))
    assert _damping_ok(_fit_with(-2.0, 1.0))  # within the noise of 0
    assert not _damping_ok(_fit_with(-11.3, 2.0))  # 5.6 stds below 0: the cart would gain energy moving
