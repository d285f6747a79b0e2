"""Tests of wholebody.motion.bases: wheel maps, constraints, exact odometry (paper eq. 4-12)."""

from __future__ import annotations

import numpy as np
import pytest

from studies import wmra_closed_form as cf
from wholebody.motion.bases import DifferentialDrive, Omnidirectional, integrate_body_displacement
from wholebody.errors import WholeBodyError

L1, L2, L3, L5 = 0.5, 0.4, 0.23, 0.17
RB = Omnidirectional(0.0759, ((0.319, 0.2755), (0.319, -0.2755), (-0.319, 0.2755), (-0.319, -0.2755)))


def _fine_integration(base, pose, rates, T=1.0, n=20000):
    """Return the pose after T s at constant wheel rates by explicit Euler with tiny steps."""
    p = np.array(pose, dtype=float)
    dt = T / n
    for _ in range(n):
        p = p + dt * (base.wheel_to_world_twist(p[2]) @ rates)
    return p


def test_diff_drive_twist_matches_paper_eq_4_5():
    base = DifferentialDrive(L1, L5)
    B = base.wheel_to_body_twist()
    wl, wr = 0.7, -0.3
    v, vy, w = B @ [wl, wr]
    assert v == pytest.approx(L5 * (wl + wr) / 2)
    assert vy == 0.0
    assert w == pytest.approx(L5 * (wr - wl) / L1)


def test_diff_drive_point_jacobian_equals_paper_eq_12():
    base = DifferentialDrive(L1, L5)
    rng = np.random.default_rng(1)
    for phi in rng.uniform(-np.pi, np.pi, 10):
        np.testing.assert_allclose(
            base.point_velocity_jacobian(phi, (L2, L3)), cf.J_whA(phi, L1, L2, L3, L5), atol=1e-12
        )
        np.testing.assert_allclose(
            base.point_velocity_jacobian_6d(phi, (L2, L3)), cf.J_whA_6d(phi, L1, L2, L3, L5), atol=1e-12
        )


def test_constraint_annihilates_feasible_motion():
    base = DifferentialDrive(L1, L5)
    rng = np.random.default_rng(2)
    for th in rng.uniform(-3, 3, 5):
        A = base.constraint_matrix(th)
        np.testing.assert_allclose(A @ base.wheel_to_world_twist(th), 0.0, atol=1e-14)
        assert A.shape == (1, 3)
        # a sideways motion violates it
        assert abs(A @ [-np.sin(th), np.cos(th), 0.0])[0] == pytest.approx(1.0)
    assert RB.constraint_matrix(0.3).shape == (0, 3)


@pytest.mark.parametrize("base", [DifferentialDrive(L1, L5), RB])
def test_exact_odometry_matches_fine_integration(base):
    rng = np.random.default_rng(3)
    pose = np.array([0.3, -0.2, 0.8])
    rates = rng.normal(size=base.n_wheels)
    exact = base.integrate(pose, rates * 1.0)
    np.testing.assert_allclose(exact, _fine_integration(base, pose, rates), atol=1e-4)


def test_odometry_equals_paper_eq_7_to_10():
    base = DifferentialDrive(L1, L5)
    pose = np.array([1.0, 2.0, 0.4])
    for dl, dr in ((0.3, 0.5), (0.5, 0.3), (-0.2, 0.9), (0.4, 0.4)):
        T = cf.ground_to_wheelchair(*pose, L5) @ cf.odometry_step(dl, dr, L1, L5)
        new = base.integrate(pose, [dl, dr])
        np.testing.assert_allclose(new[:2], T[:2, 3], atol=1e-12)
        assert np.arctan2(T[1, 0], T[0, 0]) == pytest.approx(new[2])


def test_odometry_is_continuous_through_straight_line():
    base = DifferentialDrive(L1, L5)
    pose = np.array([0.0, 0.0, 0.3])
    straight = base.integrate(pose, [1.0, 1.0])
    assert np.all(np.isfinite(straight))
    np.testing.assert_allclose(straight[:2], L5 * np.array([np.cos(0.3), np.sin(0.3)]), atol=1e-15)
    for eps in (1e-3, 1e-5, 1e-7, 1e-9, 1e-12):
        near = base.integrate(pose, [1.0 - eps, 1.0 + eps])
        # the arc leaves the straight line by about L5 * dphi / 2 laterally
        assert np.linalg.norm(near[:2] - straight[:2]) < L5 * (2 * L5 * eps / L1) + 1e-15
    # both sides of the series switch agree
    a = integrate_body_displacement(pose, (0.5, 0.01, 1e-4 * (1 - 1e-9)))
    b = integrate_body_displacement(pose, (0.5, 0.01, 1e-4 * (1 + 1e-9)))
    np.testing.assert_allclose(a, b, atol=1e-12)


def test_mecanum_inverse_kinematics_standard_form():
    r, lx, ly = 0.0759, 0.319, 0.2755
    H = RB.twist_to_wheels()
    vx, vy, wz = 0.3, -0.2, 0.5
    expected = (
        np.array(
            [vx - vy - (lx + ly) * wz, vx + vy + (lx + ly) * wz, vx + vy - (lx + ly) * wz, vx - vy + (lx + ly) * wz]
        )
        / r
    )
    np.testing.assert_allclose(H @ [vx, vy, wz], expected, atol=1e-12)
    np.testing.assert_allclose(RB.wheel_to_body_twist() @ expected, [vx, vy, wz], atol=1e-12)
    np.testing.assert_allclose(RB.body_twist_to_wheels([vx, vy, wz]), expected, atol=1e-12)


def test_bad_parameters_raise():
    with pytest.raises(WholeBodyError):
        DifferentialDrive(0.0, 0.1)
    with pytest.raises(WholeBodyError):
        Omnidirectional(0.1, ((0, 0), (1, 0)))
    with pytest.raises(WholeBodyError):
        DifferentialDrive(L1, L5).integrate([0, 0, 0], [1.0])
