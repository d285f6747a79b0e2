"""Grasp map (paper eqs. 22-25) against independent constructions."""

import numpy as np
import pinocchio as pin
import pytest

from wholebody.contacts.handle import (
    ContactSpec,
    HandleSegment,
    adjoint,
    cart_wrench,
    grasp_map,
    grasp_map_paper,
    grasp_matrix,
    wrench_basis,
    wrench_to_b,
)
from wholebody.errors import WholeBodyError


def test_wrench_basis_selects_planar_components():
    w = np.arange(1.0, 7.0)
    assert np.array_equal(wrench_basis().T @ w, [1.0, 2.0, 6.0])


def test_wrench_transport_matches_pinocchio_force_action():
    rng = np.random.default_rng(0)
    for _ in range(5):
        p = rng.normal(size=3)
        w = rng.normal(size=6)
        # the {a} frame seen from {b}: rotation I, translation p; pinocchio's act maps a force in {a} to {b}
        f_b = pin.SE3(np.eye(3), p).act(pin.Force(w[:3], w[3:])).vector
        assert np.allclose(wrench_to_b(p) @ w, f_b, atol=1e-12)


def test_adjoint_of_rotation_and_translation_matches_pinocchio():
    rng = np.random.default_rng(1)
    R = pin.rpy.rpyToMatrix(*rng.normal(size=3))
    p = rng.normal(size=3)
    assert np.allclose(adjoint(R, p), pin.SE3(R, p).action, atol=1e-12)


def test_planar_grasp_map_equals_paper_form_and_cross_product():
    rng = np.random.default_rng(2)
    p = rng.normal(size=3)
    w = rng.normal(size=6)
    G = grasp_map(p)
    # planar rows of the full transported wrench
    assert np.allclose(G @ w, (wrench_to_b(p) @ w)[[0, 1, 5]], atol=1e-12)
    # torque about the {b} origin by hand: tau_z + (p x f)_z
    assert np.isclose((G @ w)[2], w[5] + np.cross(p, w[:3])[2])
    # the paper's 6x3 map acts on the planar part of the wrench
    planar = w[[0, 1, 5]]
    assert np.allclose(grasp_map_paper(p) @ planar, wrench_to_b(p) @ (wrench_basis() @ planar))
    assert np.allclose(wrench_basis().T @ grasp_map_paper(p), G @ wrench_basis())


def test_multi_arm_sum_eq25():
    pts = [(-0.15, -0.2, 0.9), (-0.15, 0.1, 0.9), (-0.1, 0.3, 0.8)]
    W = np.random.default_rng(3).normal(size=(3, 6))
    total = sum(grasp_map(p) @ W[i] for i, p in enumerate(pts))
    assert np.allclose(cart_wrench(pts, W), total)
    assert grasp_matrix(pts).shape == (3, 18)


def test_handle_segment_geometry():
    h = HandleSegment.default(width=0.6)
    assert np.isclose(h.length, 0.6)
    assert np.allclose(h.point(0.0), (-0.15, -0.3, 0.9365))
    assert np.allclose(h.point(0.45), (-0.15, 0.15, 0.9365))
    assert np.isclose(h.coordinate(h.point(0.2)), 0.2)
    with pytest.raises(WholeBodyError):
        h.point(0.7)
    with pytest.raises(WholeBodyError):
        HandleSegment((0, 0, 0), (0, 0, 0))
    with pytest.raises(WholeBodyError):
        ContactSpec((0.0, float("nan"), 0.0))
