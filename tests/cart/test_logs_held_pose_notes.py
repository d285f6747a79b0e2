"""Issue 30: a held pose (a motion-capture dropout or a stuck pose) is not a glitch nor a heading in degrees.

Measured on every row, a naive logger's table (F/T 500 Hz, mocap 120 Hz) with a 2 s dropout while the cart
turns reads "heading changes by 0.534 rad in one sample (238 rad/s) ...; if theta is in degrees, convert it",
and a mocap-rows table whose pose sticks for 3 s "the pose moves at 31.5 m/s ...: a motion-capture glitch, or
positions in millimetres?". The plausibility notes measure the pose's own samples whenever rows repeat it, and
`estimate` names the repeated rows.
"""

from __future__ import annotations

import numpy as np

from cart.estimate_report import stream_notes
from cart.logs import CartLog, plausibility_warnings
from cart.streams import split_streams


def _turning(hz: float = 120.0, seconds: float = 30.0) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(0.0, seconds, 1.0 / hz)
    q = np.column_stack([np.cos(0.25 * t), np.sin(0.25 * t), 0.25 * t + np.pi / 2])
    return t, q + np.random.default_rng(0).normal(0.0, 5e-4, q.shape)


def test_a_dropout_in_a_held_pose_table_is_not_a_heading_in_degrees():
    t_m, q_m = _turning()
    keep = (t_m < 10.0) | (t_m > 12.0)  # 2 s without motion capture: the logger holds the last pose
    t_m, q_m = t_m[keep], q_m[keep]
    t = np.arange(0.01, 29.9, 0.002)
    q = q_m[np.searchsorted(t_m, t, side="right") - 1]
    raw = (q[:, 2] + np.pi) % (2 * np.pi) - np.pi  # written wrapped, read unwrapped
    notes = plausibility_warnings(CartLog(t=t, q=q, gamma=np.ones((len(t), 3))), raw_theta=raw)
    assert not any("degrees" in n or "glitch" in n for n in notes), notes


def test_a_stuck_pose_in_a_single_rate_table_is_named_not_taken_for_a_glitch():
    t, q = _turning()
    q[2400:2760] = q[2399]  # 3 s stuck
    log = CartLog(t=t, q=q, gamma=np.random.default_rng(1).normal(size=(len(t), 3)))
    assert not any("glitch" in n for n in plausibility_warnings(log))
    assert any("repeat a pose while the cart moved" in n for n in stream_notes(split_streams(log)))


def test_a_real_glitch_and_a_heading_in_degrees_are_still_flagged():
    t, q = _turning()
    glitch = q.copy()
    glitch[1000, 0] += 5.0
    assert any("glitch" in n for n in plausibility_warnings(CartLog(t=t, q=glitch, gamma=np.ones((len(t), 3)))))
    deg = q.copy()
    deg[:, 2] = np.degrees(deg[:, 2])
    assert any("degrees" in n for n in plausibility_warnings(CartLog(t=t, q=deg, gamma=np.ones((len(t), 3)))))
