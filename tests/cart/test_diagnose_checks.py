"""The bounded nominal fit (cart.diagnose_checks.bounded_least_squares): the reduced (QR) barrier solve against scipy."""

import numpy as np
import pytest
from scipy import optimize

from cart.diagnose_checks import GYRATION_MIN, MASS_MIN, bounded_least_squares, cart_is_physical


def _x_of(u: np.ndarray) -> np.ndarray:
    """x with J about {b}'s origin from u with the inertia about the CoM (u[3])."""
    x = np.array(u, float)
    x[3] = u[3] + (u[1] ** 2 + u[2] ** 2) / u[0]
    return x


def _jac(u: np.ndarray) -> np.ndarray:
    jac = np.eye(len(u))
    jac[3, :4] = [-(u[1] ** 2 + u[2] ** 2) / u[0] ** 2, 2.0 * u[1] / u[0], 2.0 * u[2] / u[0], 1.0]
    return jac


def _reference(a: np.ndarray, b: np.ndarray, lo3: float) -> np.ndarray:
    """The full-row fit in the box-bounded parameters (m, m dx, m dy, I about the CoM, ...) by scipy's trf."""
    n_p = a.shape[1]
    lo = np.full(n_p, -np.inf)
    lo[:6] = [MASS_MIN, -np.inf, -np.inf, lo3, 0.0, 0.0]
    u0 = np.r_[10.0, 0.0, 0.0, 1.0, 1.0, 1.0, np.zeros(n_p - 6)]
    sol = optimize.least_squares(
        lambda u: b - a @ _x_of(u),
        u0,
        jac=lambda u: -a @ _jac(u),
        bounds=(lo, np.inf),
        method="trf",
        ftol=1e-15,
        xtol=1e-15,
        gtol=1e-15,
        max_nfev=50000,
    )
    return _x_of(sol.x)


def _problem(rng: np.random.Generator, x_true: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows a (300, P) with columns of unequal scale and b = a x_true + noise."""
    a = rng.normal(size=(300, len(x_true))) * rng.uniform(0.2, 5.0, len(x_true))
    return a, a @ x_true + 0.3 * rng.normal(size=300)


@pytest.mark.parametrize("seed", range(6))
def test_the_reduced_bounded_fit_has_the_full_fits_minimiser_and_cost(seed):
    rng = np.random.default_rng(seed)
    m = rng.uniform(2.0, 40.0)
    a_b = rng.normal(0.0, 0.3 * m, 2)
    # a cart whose inertia about the CoM is negative, with a negative damping and an effect's free parameter
    x_true = np.r_[m, a_b, (a_b @ a_b) / m - rng.uniform(0.1, 1.0), rng.uniform(-2.0, 2.0), -rng.uniform(0.1, 1.0)]
    x_true = np.r_[x_true, rng.normal(size=int(seed % 3))]
    a, b = _problem(rng, x_true)
    lo3 = GYRATION_MIN**2 * m
    q, r = np.linalg.qr(a)
    c = q.T @ b
    rss0 = float(b @ b - c @ c)
    x = bounded_least_squares(r, c, x_true, lo3, rss0)
    ref = _reference(a, b, lo3)
    cost, cost_ref = float(np.sum((b - a @ x) ** 2)), float(np.sum((b - a @ ref) ** 2))
    assert cost == pytest.approx(cost_ref, rel=1e-9) and cost <= cost_ref * (1.0 + 1e-12)
    # the cost of the reduced problem plus the constant is the full cost
    assert float(np.sum((c - r @ x) ** 2)) + rss0 == pytest.approx(cost, rel=1e-9)
    # trf's own accuracy along the flat directions of the bound (its cost is never the lower one)
    assert np.allclose(x, ref, rtol=1e-6, atol=1e-9 * np.max(np.abs(ref)))
    inertia = x[3] - (x[1] ** 2 + x[2] ** 2) / x[0]
    assert cart_is_physical(x) and inertia == pytest.approx(lo3, rel=1e-6) and x[5] == pytest.approx(0.0, abs=1e-6)


def test_a_physical_unconstrained_minimiser_is_returned_as_it_is():
    rng = np.random.default_rng(11)
    x_true = np.array([12.0, 1.0, -0.5, 3.0, 2.0, 0.8, 0.4])  # I about the CoM = 3 - 1.25 / 12 > 0
    a, b = _problem(rng, x_true)
    q, r = np.linalg.qr(a)
    c = q.T @ b
    x = bounded_least_squares(r, c, np.r_[1.0, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0], GYRATION_MIN**2 * 12.0)
    assert np.allclose(x, np.linalg.lstsq(a, b, rcond=None)[0], rtol=1e-9, atol=1e-9)


def test_a_centring_whose_iterate_repeats_ends_where_the_repeated_steps_end_it():
    # _centre stops taking Newton steps once x comes back to an earlier iterate (each step is a function of x
    # alone); _periodic_end must return the x the full loop of steps would end at. Independent: the loop run
    # to its end on maps of a few states with decrements around the stop rule's thresholds.
    import math

    from cart.diagnose_checks import _MAX_NEWTON, _periodic_end, _stops

    rng = np.random.default_rng(0)
    checked = 0
    for _ in range(400):
        n = int(rng.integers(1, 12))
        nxt = rng.integers(0, n, n)
        lam_of = rng.choice([1e-6, 4e-3, 6e-3, 9e-3, 1.2e-2, 0.3], n)
        x, lam_prev, early = int(rng.integers(0, n)), math.inf, None
        xs, lams, seen = [np.array([float(x)])], [math.nan], {x: 0}
        for i in range(1, _MAX_NEWTON + 1):
            lam, x = float(lam_of[x]), int(nxt[x])
            if _stops(lam, lam_prev):
                break
            lam_prev = lam
            if early is None:
                xs.append(np.array([float(x)]))
                lams.append(lam)
                m = seen.setdefault(x, i)
                if m != i:
                    early = _periodic_end(xs, lams, m)
        if early is not None:
            assert float(early[0]) == x
            checked += 1
    assert checked > 100
