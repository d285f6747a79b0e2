"""Issue 30 item 7: a wrench in the cart frame {b} on a log whose model fits both readings is warned, not answered
silently (seed 12007's ``wrench_in_cart_frame07``: 27.9 +- 0.26 kg for a 30.0 kg cart, model_fits true, no warning).
"""

from __future__ import annotations

import math

from cart.units import FRAME_WARN_CHI2, wrench_frame_warning


def test_a_cart_frame_reading_that_fits_better_by_more_than_the_threshold_is_warned():
    w = wrench_frame_warning((1.128, 0.93), (0.982, 29.57, 0.9), 98.8)
    assert w is not None and "cart frame {b}" in w and "29.57 kg" in w


def test_a_reading_as_logged_that_fits_better_or_alike_is_not_warned():
    assert wrench_frame_warning((1.0, 0.9), (1.81, 24.9, 1.5), 98.0) is None  # {s}: {b} fits worse
    small = math.sqrt(1.0 - 0.5 * FRAME_WARN_CHI2 / 100.0)
    assert wrench_frame_warning((1.0, 0.9), (small, 30.0, small), 100.0) is None  # better by half the threshold
    assert wrench_frame_warning((1.0, 0.9), None, 100.0) is None  # not computed
    assert wrench_frame_warning((1.2, 0.9), (0.9, -3.0, 0.9), 100.0) is None  # no cart so read
