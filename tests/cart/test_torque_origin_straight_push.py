"""`estimate` reads the tool's own straight-push logs: the torque-origin check (issue 30) compares the two readings
against the same noise.

`cartpush push --trajectory 1 --duration 20 --load-change 10:+15 --out DIR` then `cartpush estimate
DIR/push_log.csv` was refused ("the torque looks taken about the world origin ... 1.44x the noise instead of
4.14x"): the torque moved by the force's moment x fy carries the lateral force's noise times the distance
travelled, and measured against its own, larger noise its residual looked small.
"""

from __future__ import annotations

import pytest

from cart.estimate_report import estimate_log
from cart.identify import identify
from cart.logs import read_log, write_log
from cart.units import UnitsError
from wholebody.push import run_push
from wholebody.push.config import LoadChange, PushConfig
from wholebody.push.report import push_log

from tests.cart.test_wrench_frame_estimate import _about_world_origin


@pytest.fixture(scope="module")
def straight_log(tmp_path_factory):
    """Traj. 1 (a straight line) for 20 s on the kinematic plant, 15 kg put in at 10 s at the CoM (the model
    misfits), written and read back as `push --out` and `estimate` do."""
    config = PushConfig(trajectory=1, duration=20.0, load_changes=(LoadChange(10.0, 15.0, None),))
    path = tmp_path_factory.mktemp("straight") / "push_log.csv"
    write_log(path, push_log(run_push(config)))
    return read_log(path)


def test_a_straight_push_log_written_by_push_is_estimated(straight_log):
    res = identify(straight_log)
    assert res.torque_origin is not None, "the load change makes the model misfit: the origin check runs"
    assert res.torque_origin > res.residual_ratio[1], (res.torque_origin, res.residual_ratio)
    est = estimate_log(straight_log)
    assert 15.0 < est.params.m < 40.0


def test_the_same_log_with_its_torque_about_the_world_origin_is_refused(straight_log):
    with pytest.raises(UnitsError, match="world origin"):
        estimate_log(_about_world_origin(straight_log))
