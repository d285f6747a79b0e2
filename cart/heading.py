"""Unwrapping a logged heading that motion capture glitches through: a sample flipped by about pi.

``np.unwrap`` adds the multiple of 2 pi that makes each step smallest. A motion-capture sample whose heading
is off by about pi (a quaternion's sign or a marker swap) is a step of about pi out and one back; each is read
as +pi or -pi by the noise on it, and when both come out with one sign the heading after the glitch is left
2 pi off, or pi when the return was read the other way: the cart then seems to move backwards for the rest of
the log. :func:`unwrap_heading` unwraps each such excursion against the sample before it, so the heading after
it continues the heading before, and the glitched samples stay single spikes (`cart.streams` drops them).
"""

from __future__ import annotations

import math

import numpy as np

#: a heading step larger than this (rad) between two samples is no cart's turn: a glitch or a jump
BIG_STEP = math.pi / 2
#: an excursion that returns within this time (s) is a glitch; one that does not is a jump that stays
GLITCH_S = 1.0


def _wrap(a: np.ndarray | float) -> np.ndarray:
    """Return angle(s) wrapped to [-pi, pi)."""
    return (np.asarray(a, dtype=float) + math.pi) % (2.0 * math.pi) - math.pi


def unwrap_heading(t: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Return the heading unwrapped (``np.unwrap``), each excursion of a big step (`BIG_STEP`) that returns to the
    heading before it within `GLITCH_S` made to return there (not 2 pi or pi off)."""
    theta = np.asarray(theta, dtype=float)
    out = np.unwrap(theta)
    if len(theta) < 3:
        return out
    big = np.flatnonzero(np.abs(_wrap(np.diff(theta))) > BIG_STEP)
    k = 0
    while k < len(big):
        i = int(big[k])  # the excursion leaves after sample i
        stop = int(np.searchsorted(t, t[i + 1] + GLITCH_S, side="right"))
        back = np.flatnonzero(np.abs(_wrap(theta[i + 2 : stop] - theta[i])) <= BIG_STEP)
        if back.size == 0:  # no return within the time: a jump that stays
            k += 1
            continue
        j = i + 2 + int(back[0])  # the first sample back near the heading before
        turns = round((out[j] - out[i] - float(_wrap(theta[j] - theta[i]))) / (2.0 * math.pi))
        if turns:
            out[j:] -= 2.0 * math.pi * turns
        k = int(np.searchsorted(big, j - 1, side="right"))
    return out
