"""Push scenes: the robot holding the cart's handle, and one Table I test animated (`cartpush view --scenario N`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

import robots
from robots.shopping_cart import CART_HANDLE_Z_B, CART_WHEEL_RADIUS
from cart.table1 import TESTS, contact_point, run_test
from wholebody.viz import COM_MARKER_Z, Scene, SceneError, cart_to_world_traj, cover_floor


def pushing_configuration(
    cart_pose: Sequence[float] = (0.9, 0.0, 0.0), contact_y: float = 0.0, robot: str = "ridgeback_iiwa"
) -> tuple[np.ndarray, np.ndarray]:
    """Return (base planar pose, full q) of `robot` holding the cart's handle at `contact_y` (m, in {b}).

    The grasp of the push loop (`wholebody.push.robot`): the base stands where the
    robot's profile puts it behind the handle (`push_base_x`, `push_base_y`, else
    behind the contact), the hand holds the bar at the profile's grasp pitch, and
    the arm comes from `solve_grasp_ik` seeded with the profile's push posture.
    """
    from robots.profiles import profile
    from wholebody.motion.kinematics import wholebody_for
    from wholebody.push.robot import grasp_configuration, push_grasp_rotation, push_profile

    if not profile(robot).is_mobile_manipulator:
        raise SceneError(f"robot {robot!r} has no arm on a wheeled base in its profile; it does not push the cart")
    q_cart = np.asarray(cart_pose, dtype=float).ravel()
    if q_cart.shape != (3,) or not np.all(np.isfinite(q_cart)):
        raise SceneError(f"cart pose must be 3 finite numbers (x, y, theta), got {cart_pose!r}")
    loaded = robots.load(robot)
    prof = push_profile(loaded)  # tuned settings, or computed from the URDF (grasp, base place, posture)
    wb = wholebody_for(loaded, base_input=prof.base_input)
    base_y = contact_y if prof.push_base_y is None else prof.push_base_y
    base, arm = grasp_configuration(wb, prof, q_cart, contact_y, base_y, push_grasp_rotation(prof))
    return base, wb.to_pinocchio_q(np.r_[base, arm])


def pushing_scene(cart_pose: Sequence[float] = (0.9, 0.0, 0.0), serve: bool = False) -> Scene:
    """Return the Ridgeback + iiwa holding the middle of the cart's handle, the cart at planar pose `cart_pose`."""
    scene = Scene(["ridgeback_iiwa", "shopping_cart"], serve=serve)
    _, q = pushing_configuration(cart_pose)
    scene.set_robot_q("ridgeback_iiwa", q)
    scene.set_robot_pose("shopping_cart", cart_pose)
    return scene


def scenario_scene(test: int, duration: float = 30.0, serve: bool = False, fps: int = 30) -> Scene:
    """Return an animated scene of Table I test `test` (1..11): simulated cart, robot, force, contact, CoM estimate.

    Runs `cart.table1.run_test` (with estimation). The robot keeps the arm
    pose of `pushing_configuration` and its base rigidly behind the cart (a
    display convention: the simulation has the cart alone); the force arrow
    sits at the simulation's contact point; the estimated CoM (magenta)
    converges towards the true one (blue); the traces are the desired (grey)
    and the actual (cyan) paths. The page plays when opened; its camera starts
    on the robot and the cart and follows them; the overlay shows the force
    (N), the mass estimate (kg) and the CoM error (cm) live, and the legend.
    """
    numbers = [spec.test for spec in TESTS]
    if test not in numbers:
        raise SceneError(f"unknown Table I test {test}; valid: {numbers[0]}..{numbers[-1]}")
    spec = TESTS[numbers.index(test)]
    run = run_test(spec, duration=duration)
    base0, q_robot = pushing_configuration((0.0, 0.0, 0.0))
    q = np.asarray(run.q, float)
    base = cart_to_world_traj(q, np.tile(base0[:2], (len(q), 1)), 0.0)
    base[:, 2] = q[:, 2]
    contact_fn = contact_point(spec)
    contact_b = np.array([contact_fn(t) for t in run.t])
    handle_z = CART_HANDLE_Z_B + CART_WHEEL_RADIUS
    contact = cart_to_world_traj(q, contact_b, handle_z)
    com_z = COM_MARKER_Z
    com_true = cart_to_world_traj(q, np.asarray(run.params_true)[:, 1:3], com_z)
    com_est = cart_to_world_traj(q, np.asarray(run.params_hat)[:, 1:3], com_z)

    scene = Scene(["ridgeback_iiwa", "shopping_cart"], serve=serve)
    scene.show_trace("desired", np.asarray(run.q_desired)[:, :2], color=0x8A8F98, label="grey line: desired path")
    scene.show_trace("actual", q[:, :2], label="cyan line: the cart's simulated path")
    scene.show_contact("arm0", contact_b[:1], frame="b")
    scene.show_com(np.asarray(run.params_true)[0, 1:3], np.asarray(run.params_hat)[0, 1:3])
    _readouts(scene, run)
    scene.animate(
        run.t,
        {"ridgeback_iiwa": base, "shopping_cart": q},
        q_joints={"ridgeback_iiwa": np.tile(q_robot[4:], (len(q), 1))},
        wrenches={"arm0": (contact, np.asarray(run.gamma)[:, :2])},
        markers={"contacts/arm0/0": contact, "com/com_true": com_true, "com/com_est": com_est},
        fps=fps,
        follow=("ridgeback_iiwa", "shopping_cart"),
    )
    cover_floor(np.vstack((q[:, :2], base[:, :2])), scene)
    scene.frame_robots(margin=0.6)  # the first frame, large on screen; the camera then follows
    return scene


def _readouts(scene: Scene, run) -> None:
    """Add the live read-outs of a Table I run: force (N), mass estimate (kg), CoM error (cm)."""
    gamma, true, hat = np.asarray(run.gamma), np.asarray(run.params_true), np.asarray(run.params_hat)
    scene.add_readout("force on the cart |f|", "N", run.t, np.hypot(gamma[:, 0], gamma[:, 1]))
    scene.add_readout("mass (EKF estimate)", "kg", run.t, hat[:, 0])
    scene.add_readout("true mass", "kg", run.t, true[:, 0])
    scene.add_readout("CoM error", "cm", run.t, 100 * np.hypot(*(hat[:, 1:3] - true[:, 1:3]).T))
