"""A covariance with a non-finite variance (a column the log never excites: a heading that never changes, so
m dx and the yaw damping are free) must not crash the closest-physical-body fit: the malformed suite's
``tiny_block`` log (heading always 0) raised ``LinAlgError: Eigenvalues did not converge`` (exit 1)."""

from __future__ import annotations

import numpy as np

from cart.physical import _physical_margins, constrained_fit


def test_a_parameter_without_a_finite_variance_is_free_in_the_physical_fit():
    p_hat = np.array([8.1, 1e-11, 0.07, -9.4e-5, 2.87, 1e-17])  # I about the CoM < 0: not physical
    cov = np.diag([3.5, -np.inf, 1.5, 7.5e-8, 2.3, -np.inf])
    cov[0, 2] = cov[2, 0] = 0.1
    p = constrained_fit(p_hat, cov)
    assert np.all(np.isfinite(p))
    margins = _physical_margins(p)
    assert margins[0] > 0 and margins[1] > 0 and min(margins[2:]) >= 0
    assert abs(p[0] - p_hat[0]) < 0.5  # the mass barely moves: the inertia is fixed by the free columns
