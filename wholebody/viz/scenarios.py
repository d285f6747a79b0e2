"""A Meshcat scene of one Table I test (`cartpush view --scenario N`): the study's run, animated."""

from __future__ import annotations

import numpy as np

from robots.shopping_cart import CART_HANDLE_Z_B, CART_WHEEL_RADIUS
from cart.table1 import TESTS, contact_point, run_test
from wholebody.viz import COM_MARKER_Z, Scene, SceneError, cart_to_world_traj, frame_points, pushing_configuration


def scenario_scene(test: int, duration: float = 30.0, serve: bool = False, fps: int = 30) -> Scene:
    """Return an animated scene of Table I test `test` (1..11): simulated cart, robot, force, contact, CoM estimate.

    Runs `cart.table1.run_test` (with estimation). The robot keeps the arm
    pose of `pushing_configuration` and its base rigidly behind the cart (a
    display convention: the simulation has the cart alone); the force arrow
    sits at the simulation's contact point; the estimated CoM (magenta)
    converges towards the true one (blue); the traces are the desired (grey)
    and the actual (purple) paths.
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
    scene.show_trace("desired", np.asarray(run.q_desired)[:, :2], color=0x8A8F98)
    scene.show_trace("actual", q[:, :2])
    scene.show_contact("arm0", contact_b[:1], frame="b")
    scene.show_com(np.asarray(run.params_true)[0, 1:3], np.asarray(run.params_hat)[0, 1:3])
    scene.animate(
        run.t,
        {"ridgeback_iiwa": base, "shopping_cart": q},
        q_joints={"ridgeback_iiwa": np.tile(q_robot[4:], (len(q), 1))},
        wrenches={"arm0": (contact, np.asarray(run.gamma)[:, :2])},
        markers={"contacts/arm0/0": contact, "com/com_true": com_true, "com/com_est": com_est},
        fps=fps,
    )
    frame_points(np.vstack((np.column_stack((q[:, :2], np.zeros(len(q)))), base)), scene)
    return scene
