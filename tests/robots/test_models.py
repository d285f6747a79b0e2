"""Robot models: D-H forward kinematics, inertial consistency, the WMRA family, the cart's mass."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import robots
from robots.errors import RobotError, UnknownRobotError
from robots.wmra import WMRA_ALPHA, WMRA_D, WMRA_MOUNT

README = Path(robots.__file__).with_name("README.md")


def dh_modified(alpha: float, a: float, theta: float, d: float) -> np.ndarray:
    """Paper eq. (1): the modified D-H transform from frame i-1 to frame i."""
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array(
        [
            [ct, -st, 0.0, a],
            [st * ca, ct * ca, -sa, -sa * d],
            [st * sa, ct * sa, ca, ca * d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def arm_q(robot: robots.LoadedRobot, q_arm: np.ndarray, prefix: str) -> np.ndarray:
    q = pin.neutral(robot.model)
    for i, qi in enumerate(q_arm, start=1):
        q[robot.model.joints[robot.model.getJointId(f"{prefix}{i}")].idx_q] = qi
    return q


def test_wmra_fk_equals_product_of_dh_matrices():
    """Paper eq. (1)-(2) at 100 random configurations, to 1e-9."""
    r = robots.load("wmra")
    rng = np.random.default_rng(0)
    fa, fe = r.frame_id("arm_base"), r.frame_id("ee")
    worst = 0.0
    for _ in range(100):
        q_arm = rng.uniform(-math.pi, math.pi, 7)
        q = arm_q(r, q_arm, "arm_joint")
        base = rng.uniform(-3, 3, 3)
        q[:4] = [base[0], base[1], math.cos(base[2]), math.sin(base[2])]
        pin.framesForwardKinematics(r.model, r.data, q)
        T_A_E = (r.data.oMf[fa].inverse() * r.data.oMf[fe]).homogeneous
        T = np.eye(4)
        for i in range(7):
            T = T @ dh_modified(WMRA_ALPHA[i], 0.0, q_arm[i], WMRA_D[i])
        worst = max(worst, np.abs(T - T_A_E).max())
    assert worst < 1e-9


def test_wmra_mount_is_eq8_from_axle_centre():
    r = robots.load("wmra")
    q = pin.neutral(r.model)
    pin.framesForwardKinematics(r.model, r.data, q)
    T_W_A = r.data.oMf[r.frame_id("base")].inverse() * r.data.oMf[r.frame_id("arm_base")]
    assert np.allclose(T_W_A.translation, WMRA_MOUNT, atol=1e-12)
    assert np.allclose(T_W_A.rotation, np.eye(3), atol=1e-12)
    # eq. (9): the wheelchair frame sits L5 above the floor
    assert r.data.oMf[r.frame_id("base")].translation[2] == pytest.approx(robots.wmra.WMRA_WHEEL_RADIUS)


def test_shipped_wmra_urdf_is_the_generator_default():
    assert robots.urdf_path("wmra").read_text() == robots.wmra_urdf()
    assert robots.urdf_path("ridgeback_iiwa").read_text() == robots.ridgeback_iiwa_urdf()
    assert robots.urdf_path("shopping_cart").read_text() == robots.shopping_cart_urdf()


def test_wmra_family_other_build_changes_kinematics():
    d = [0.1204, 0.13425, 0.503345, 0.1332, 0.386658, -0.0235, 0.3775]
    r = robots.load("wmra", urdf_text=robots.wmra_urdf(d=d, track=0.56, mount=(0.44, 0.23, 0.182), wheel_radius=0.168))
    q_arm = np.array([0.3, 1.2, -0.4, 1.0, 0.2, 0.5, -0.7])
    q = arm_q(r, q_arm, "arm_joint")
    pin.framesForwardKinematics(r.model, r.data, q)
    T = (r.data.oMf[r.frame_id("arm_base")].inverse() * r.data.oMf[r.frame_id("ee")]).homogeneous
    T_dh = np.eye(4)
    for i in range(7):
        T_dh = T_dh @ dh_modified(WMRA_ALPHA[i], 0.0, q_arm[i], d[i])
    assert np.allclose(T, T_dh, atol=1e-12)
    wl = r.model.joints[r.model.getJointId("wheel_left_joint")]
    assert r.model.jointPlacements[r.model.getJointId("wheel_left_joint")].translation[1] == pytest.approx(0.28)
    assert wl.nv == 1


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"d": [0.1] * 6}, "7 D-H offsets"),
        ({"track": -0.5}, "positive"),
        ({"mount": (0.4, 0.2)}, "L2, L3, L4"),
        ({"d": [102, 133, 502, 90, 375, 0, 304]}, "millimetres"),
        ({"wheel_radius": float("nan")}, "finite"),
    ],
)
def test_wmra_urdf_rejects_bad_dimensions(kwargs, match):
    with pytest.raises(RobotError, match=match):
        robots.wmra_urdf(**kwargs)


@pytest.mark.parametrize("name", robots.available())
def test_inertias_are_physically_consistent(name):
    r = robots.load(name)
    for i, inertia in enumerate(r.model.inertias[1:], start=1):
        if inertia.mass == 0.0:
            continue
        assert inertia.mass > 0, r.model.names[i]
        eig = np.linalg.eigvalsh(inertia.inertia)  # about the CoM
        assert eig.min() > 0, r.model.names[i]
        a, b, c = sorted(eig)
        assert a + b >= c - 1e-12, f"triangle inequality fails for {r.model.names[i]}"


def test_ridgeback_iiwa_mass_and_chain():
    r = robots.load("ridgeback_iiwa")
    # RB: chassis + 2 rockers + 4 wheels; Drake iiwa 30.61; FT-300 0.3; 2F-85 0.905
    assert pin.computeTotalMass(r.model) == pytest.approx(
        165.304 + 2 * 10.267 + 4 * 2.3 + 30.61 + 0.3 + 0.905, abs=1e-9
    )
    q = pin.neutral(r.model)
    pin.framesForwardKinematics(r.model, r.data, q)
    base0 = r.data.oMf[r.frame_id("arm_base")].translation[2]
    flange = r.data.oMf[r.frame_id("flange")].translation[2]
    assert flange - base0 == pytest.approx(1.306, abs=1e-9)  # reference: flange at 1.306 m
    for lim, name in zip((320, 320, 176, 176, 110, 40, 40), range(1, 8)):
        jid = r.model.getJointId(f"iiwa_joint_{name}")
        assert r.model.effortLimit[r.model.joints[jid].idx_v] == pytest.approx(lim)


def _readme_row(label: str) -> list[float]:
    for line in README.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if cells and cells[0] == label:
            return [float(x) for x in re.split(r"[,\s]+", cells[1]) if x]
    raise AssertionError(f"robots/README.md has no row {label!r}")


def test_cart_mass_and_com_are_what_the_readme_states():
    r = robots.load("shopping_cart")
    q = pin.neutral(r.model)
    rng = np.random.default_rng(3)
    th = rng.uniform(-3, 3)
    q[:4] = [1.3, -0.7, math.cos(th), math.sin(th)]
    com_s = pin.centerOfMass(r.model, r.data, q)
    pin.framesForwardKinematics(r.model, r.data, q)
    com_b = r.data.oMf[r.frame_id("b")].actInv(com_s)
    assert pin.computeTotalMass(r.model) == pytest.approx(_readme_row("cart total mass")[0], abs=1e-9)
    assert np.allclose(com_b, _readme_row("cart CoM in frame b (x, y, z)"), atol=5e-5)
    pin.ccrba(r.model, r.data, q, np.zeros(r.model.nv))
    assert r.data.Ig.inertia[2, 2] == pytest.approx(_readme_row("cart yaw inertia about the CoM")[0], abs=5e-5)


def test_cart_handle_frame():
    r = robots.load("shopping_cart")
    q = pin.neutral(r.model)
    pin.framesForwardKinematics(r.model, r.data, q)
    h = r.data.oMf[r.frame_id("handle")].translation
    assert np.allclose(h, [-0.15, 0.0, 1.0], atol=1e-12)


def test_unknown_robot_lists_valid_names():
    with pytest.raises(UnknownRobotError, match="ridgeback_iiwa, shopping_cart, wmra"):
        robots.load("pr2")


def test_load_exposes_models_and_frames():
    r = robots.load("ridgeback_iiwa")
    assert r.model.nv == 3 + 7 + 4
    assert len(r.visual_model.geometryObjects) > 10
    assert r.model.existFrame("ft_sensor") and r.model.existFrame("ee")
    with pytest.raises(UnknownRobotError, match="no frame"):
        r.frame_id("nonexistent")


def test_custom_build_keeps_a_readable_urdf_and_its_base_dimensions():
    from wholebody.motion.kinematics import wholebody_for

    text = robots.wmra_urdf(track=0.56, wheel_radius=0.168)
    r = robots.load("wmra", urdf_text=text)
    assert r.urdf.read_text() == text
    wb = wholebody_for(r)
    assert wb.base.track == pytest.approx(0.56) and wb.base.wheel_radius == pytest.approx(0.168)
