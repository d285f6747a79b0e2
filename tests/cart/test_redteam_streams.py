"""Issue 30, multi-rate tables: a logger that interpolates the pose linearly to the F/T times.

Besides holding the last pose (``held_pose``) or averaging the F/T per pose (``mocap_rows``), a logger
may interpolate motion capture linearly to every F/T time. The table then holds straight pieces between
the motion-capture samples; read as a 500 Hz pose, its kinks look like glitches and the estimate loses
the mass (rigid_sim seed 330, 500 Hz F/T, 120 Hz motion capture: mass "not identified", std 0.0005 kg;
split into streams: 99.5 kg for 99.7). A measured pose at the F/T rate and a noise-free cruise are left alone.
"""

from __future__ import annotations

import numpy as np
import pytest

from cart import table1
from cart.logs import CartLog
from cart.streams import split_streams


def _motion(t: np.ndarray) -> np.ndarray:
    return np.column_stack([np.sin(0.3 * t), 0.5 * t, 0.1 * t + 0.2 * np.sin(0.7 * t)])


def _interpolated(
    ft_hz: float = 500.0, mocap_hz: float = 120.0, seconds: float = 20.0, decimals: int | None = None
) -> tuple[CartLog, np.ndarray]:
    rng = np.random.default_rng(4)
    t = np.arange(0.0, seconds, 1.0 / ft_hz) + rng.normal(0.0, 2e-5, int(round(seconds * ft_hz)))
    t_m = np.arange(0.0, seconds, 1.0 / mocap_hz) + 0.3 / mocap_hz
    keep = (t_m < 8.0) | (t_m > 8.4)  # a 0.4 s motion-capture dropout
    t_m = t_m[keep]
    pose = _motion(t_m) + rng.normal(0.0, 1e-3, (len(t_m), 3))
    rows = (t >= t_m[0]) & (t <= t_m[-1])
    q = np.column_stack([np.interp(t[rows], t_m, pose[:, k]) for k in range(3)])
    t = t[rows]
    if decimals is not None:  # written with a fixed number of decimals
        t, q = np.round(t, decimals), np.round(q, decimals)
    return CartLog(t=t, q=q, gamma=rng.standard_normal((len(t), 3))), t_m


@pytest.mark.parametrize("decimals", [None, 6])
def test_an_interpolated_pose_is_read_at_its_own_samples(decimals):
    log, t_m = _interpolated(decimals=decimals)
    st = split_streams(log)
    near = np.abs(t_m[:, None] - st.pose.t[None, :]).min(axis=0)
    assert len(st.pose.t) > 0.98 * len(t_m) and np.max(near) < (1e-9 if decimals is None else 1e-4)
    assert st.multi_rate and st.interpolated and not st.glitches
    assert 110 < st.pose_hz < 130 and 495 < st.wrench_hz < 505
    assert any(t0 < 8.2 < t1 for t0, t1 in st.dropouts)  # the dropout is a gap, not a straight piece of motion
    assert any("interpolated linearly" in w for w in st.warnings())


def test_a_measured_pose_and_a_noise_free_cruise_are_not_interpolated_tables():
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 20.0, 0.002)
    noisy = CartLog(t=t, q=_motion(t) + rng.normal(0.0, 1e-3, (len(t), 3)), gamma=rng.standard_normal((len(t), 3)))
    cruise_q = np.column_stack([0.5 * t, 0.2 * t + 1.0, 0.0 * t + 0.38])  # straight at constant speed
    cruise = CartLog(t=t, q=cruise_q, gamma=rng.standard_normal((len(t), 3)))
    run = table1.run_test(table1.TESTS[5], True, duration=30.0)  # noise-free, smooth: changes of every size
    smooth = CartLog(t=run.t, q=run.q, gamma=run.gamma)
    for log in (noisy, cruise, smooth):
        st = split_streams(log)
        assert not st.interpolated and st.held_rows == 0 and len(st.pose.t) == len(log.t)


def test_a_pose_at_rest_is_no_interpolated_table():
    """Ten rows of a pose at rest (one straight piece, no corners) under a growing wrench: read as they are.

    The hypothesis example of tests/cart/test_bad_input_property.py that made `cartpush estimate` exit 1
    (an IndexError in the corner search) instead of refusing the log.
    """
    t = np.array([0.00121914, 0.0018508, 0.00211636, 0.0023428, 0.00384403])
    t = np.r_[t, 0.00550444, 0.00667506, 0.00804225, 0.00911205, 0.01080817]
    gamma = np.column_stack([10.0 + 4.0 * (t - t[0]), np.zeros(10), 2.0 * (t - t[0])])
    streams = split_streams(CartLog(t=t, q=np.zeros((10, 3)), gamma=gamma))
    assert not streams.interpolated
