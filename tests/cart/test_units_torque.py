"""A torque written in N mm (x1000) is refused, as positions in mm, heading in degrees and time in ms are.

Read as it is, tau in N mm leaves the forward row alone and scales the yaw row by 1000: the model fits as
well, with a yaw inertia 1000 times too large (the h31 tester's units_tau_Nmm: 7476 +- 3023 kg m^2 for 2.39,
exit 0, no warning). The torque about {b}'s origin is the force's moment, at most |F| times the distance
from {b} to where the force is applied (a cart's size): a torque whose scale needs a lever arm of tens of
metres is not in N m.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cart.diagnose import diagnose
from cart.estimate_report import estimate_log
from cart.logs import CartLog, write_log
from cart.streams import split_streams
from cart.units import MAX_LEVER_ARM, UnitsError, check_units, lever_arm
from studies.testbeds import log_recorders as lr
from studies.testbeds import rigid_sim


@pytest.fixture(scope="module")
def log() -> CartLog:
    """A 40 s push of the independent simulator, recorded as mocap rows with AR(1) F/T noise and an offset."""
    return lr.mocap_rows_table(lr.record(rigid_sim.random_case(101, duration=40.0), seed=1))


def _tau_scaled(log: CartLog, factor: float) -> CartLog:
    """Return ``log`` with its torque column multiplied by ``factor``."""
    return replace(log, gamma=log.gamma * [1.0, 1.0, factor])


def _tau_at_arm(log: CartLog, arm: tuple[float, float]) -> CartLog:
    """Return ``log`` with tau the moment about {b}'s origin of its force applied at ``arm`` (m, in {b})."""
    th = log.q[:, 2]
    rx = np.cos(th) * arm[0] - np.sin(th) * arm[1]  # the arm in {s}
    ry = np.sin(th) * arm[0] + np.cos(th) * arm[1]
    tau = rx * log.gamma[:, 1] - ry * log.gamma[:, 0]
    return replace(log, gamma=np.column_stack([log.gamma[:, :2], tau]))


def test_the_recorded_torque_has_the_lever_arm_of_a_cart(log):
    arm = lever_arm(split_streams(log).wrench.values)
    assert 0.0 < arm < 1.0, arm


def test_the_lever_arm_is_the_force_s_distance_from_the_origin(log):
    # a push at 2.5 m from {b} (a long bed pushed at its far end) is no unit mistake: |tau| <= 2.5 m |F| on every
    # sample, so the percentiles' ratio is at most the arm, and the force's changing direction keeps it near it
    far = _tau_at_arm(log, (-2.0, 1.5))
    assert 0.3 * 2.5 < lever_arm(far.gamma) <= 2.5 * (1 + 1e-12)
    check_units(split_streams(far), "far.csv")


def test_a_torque_in_newton_millimetres_is_refused_by_estimate_and_diagnose(log):
    nmm = _tau_scaled(log, 1000.0)
    assert lever_arm(nmm.gamma) > MAX_LEVER_ARM
    for run in (estimate_log, diagnose):
        with pytest.raises(UnitsError, match=r"tau looks like N mm \(x1000\); divide tau by 1000"):
            run(nmm)


def test_the_command_line_exits_2_naming_the_file_and_the_fix(log, tmp_path, capsys):
    from cartpush.cli import main

    path = tmp_path / "tau_nmm.csv"
    write_log(path, _tau_scaled(log, 1000.0))
    assert main(["estimate", str(path), "--json"]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "divide tau by 1000" in err and len(err.strip().splitlines()) == 1
