"""Tests of the paper's §IV experiments: WMRA tracking accuracy and limits at every step, safety band."""

from __future__ import annotations

import numpy as np
import pytest

import robots
from wholebody.motion.experiments import run_tracking
from wholebody.motion.kinematics import wholebody_for

TOL = 1e-9


def _assert_limits(res, wb):
    q = res.x[:, 3:]
    assert np.all(q >= wb.arm_lower - TOL) and np.all(q <= wb.arm_upper + TOL)
    assert np.all(np.abs(res.u[:, : wb.n_arm]) <= wb.arm_velocity_limit + TOL)
    assert np.all(np.abs(res.wheel_rates) <= wb.wheel_velocity_limit * (1 + TOL))
    assert np.all(np.isfinite(res.x)) and np.all(np.isfinite(res.u))


@pytest.fixture(scope="module")
def wmra():
    return wholebody_for(robots.load("wmra"))


@pytest.mark.parametrize("path", ["line", "sine"])
def test_wmra_experiment_tracks_within_paper_bounds(wmra, path):
    res = run_tracking("wmra", path, wb=wmra)
    assert res.steps == 6000 and res.dt == pytest.approx(0.01)
    # recompute the errors independently from the stored states
    errs = np.array(
        [np.linalg.norm(wmra.ee_placement(x).translation - p) for x, p in zip(res.x[::50], res.ee_desired[::50])]
    )
    assert errs.max() <= res.max_position_error_m + 1e-12
    assert res.rms_position_error_m < 1e-3
    assert res.max_position_error_m < 5e-3
    assert res.max_orientation_error_rad < 5e-3
    _assert_limits(res, wmra)
    assert res.min_joint_limit_margin_rad > 0
    assert res.solver_failures == 0
    # the desired path is the paper's: 5.4 m along X (+ 1 m sine in Y)
    d = res.ee_desired[-1] - res.ee_desired[0]
    assert d[0] == pytest.approx(5.4)
    assert d[1] == pytest.approx(np.sin(6.0) if path == "sine" else 0.0, abs=1e-12)
    # the base really drove (the arm alone cannot reach 5.4 m)
    assert res.x[-1, 0] - res.x[0, 0] > 4.5


def test_wmra_band_keeps_base_inside(wmra):
    res = run_tracking("wmra", "sine", band_radius=0.5, duration=20.0, wb=wmra)
    dist = np.linalg.norm(res.x[:, :2] - res.band_center, axis=1)
    assert dist.max() <= 0.5 + 1e-6
    assert res.max_band_distance_m == pytest.approx(dist.max())
    _assert_limits(res, wmra)
    free = run_tracking("wmra", "sine", duration=20.0, wb=wmra)
    assert np.linalg.norm(free.x[:, :2] - free.band_center, axis=1).max() > 0.5  # the band binds


def test_ridgeback_band_sine_tracks_and_holds_band():
    res = run_tracking("ridgeback_iiwa", "sine", band_radius=0.7, duration=30.0)
    wb = wholebody_for(robots.load("ridgeback_iiwa"), "twist")
    _assert_limits(res, wb)
    assert res.max_band_distance_m <= 0.7 + 1e-5
    assert res.max_position_error_m < 5e-3
    free = run_tracking("ridgeback_iiwa", "sine", duration=30.0)
    assert np.linalg.norm(free.x[:, :2] - free.band_center, axis=1).max() > 0.7


def test_a_profile_robot_whose_mid_range_is_near_singular_starts_bent():
    """TIAGo++ (no push_seed): the middle of its arm's ranges leaves the combined Jacobian's smallest singular value
    at 0.024; the start is the best-conditioned of the bent candidates, within the limits, and tracks the sine
    without a singular step. A robot whose middle is well conditioned (the WMRA as a profile) keeps it."""
    import numpy as np

    import robots
    from wholebody.motion import experiments as ex
    from wholebody.motion.kinematics import wholebody_for

    loaded = robots.load("robots/examples/tiago_dual.toml")
    wb = wholebody_for(loaded, loaded.profile.base_input)
    mid = 0.5 * (wb.arm_lower + wb.arm_upper)
    start = ex.initial_state(wb)[3:]
    assert ex._sigma_min(wb, mid) < ex.START_SIGMA_MIN <= ex._sigma_min(wb, start)
    assert np.all(start > wb.arm_lower) and np.all(start < wb.arm_upper)
    res = ex.run_tracking("robots/examples/tiago_dual.toml", "sine", duration=3.0, wb=wb)
    assert res.singular_steps == 0 and res.rms_position_error_m < 1e-3
    wmra = robots.load("wmra")
    wb2 = wholebody_for(wmra, "wheels")
    mid2 = 0.5 * (wb2.arm_lower + wb2.arm_upper)
    assert ex._sigma_min(wb2, mid2) >= ex.START_SIGMA_MIN and np.array_equal(ex._unfolded_mid_range(wb2), mid2)
