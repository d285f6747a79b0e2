"""Two torque-controlled arms on one cart (two Ridgeback + iiwa, `MujocoPlantConfig.multi_arm_force_loop`).

Each hand pushes the free cart forward with its share of a push while both bases stand still: the cart and the
hands accelerate away from the bases, and each arm's task-space inertia (19 kg along the push at the iiwa's push
posture, as much as the cart) takes part of ``J^T w`` unless the arm's force loop gives it back: with the default
loops each hand delivers most of its allocated force, open-loop (``"off"``) the cart gets a fraction of it.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.wholebody.push.mujoco_hold import hold_commands, quiet_plant
from wholebody.push import PushConfig, build_controller
from wholebody.push.mujoco_plant import MujocoPlantConfig

PUSH = 15.0  # N per hand, forward in the world (the cart's x at the start)
STEPS = 30  # control periods (0.3 s: the hands move about 10 cm from their bases)


@pytest.fixture(scope="module")
def setup():
    return build_controller(PushConfig(trajectory=1, duration=2.0, contact="fixed", n_arms=2))


def _hand_force_errors(setup, mode: str) -> np.ndarray:
    """Return, per period after the first 5, each hand's period-mean force minus its allocated one (N, x y z)."""
    plant = quiet_plant(setup, config=MujocoPlantConfig(multi_arm_force_loop=mode))
    wrench = np.array([PUSH, 0.0, 0.0, 0.0, 0.0, 0.0])
    errors = []
    for k in range(STEPS):
        cmds = hold_commands(plant, wrench)
        plant.step(cmds)
        if k >= 5:
            errors.append([w[:3] - wrench[:3] for w in plant._hand_clean])
    return np.array(errors)


def test_default_loops_give_back_the_push_the_arms_inertia_takes(setup):
    assert MujocoPlantConfig().multi_arm_force_loop == "full"
    closed = _hand_force_errors(setup, "full")
    open_loop = _hand_force_errors(setup, "off")
    short_open, short_closed = -open_loop[:, :, 0].mean(), -closed[:, :, 0].mean()
    # open loop the arms' inertia takes a large share of the push
    assert short_open > 0.25 * PUSH, short_open
    # the loops give each hand back at least half of what its arm's inertia took (P + I against an acceleration
    # that grows as the elbows open: in 0.3 s the integral does not remove it all)
    assert short_closed < 0.5 * short_open, (short_closed, short_open)

    # and less squeeze between the hands (their y forces opposed: the arms' task-space inertia couples x and y)
    def squeeze_y(e: np.ndarray) -> float:
        return float(np.abs(0.5 * (e[:, 0, 1] - e[:, 1, 1])).max())

    assert squeeze_y(closed) < squeeze_y(open_loop), (squeeze_y(closed), squeeze_y(open_loop))
