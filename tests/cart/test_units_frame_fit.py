"""The cart-frame refusal needs the {b} reading to fit (cart.units.check_wrench_frame), as the torque-origin one."""

from __future__ import annotations

import pytest

from cart.identify import FIT_RATIO
from cart.units import UnitsError, check_wrench_frame, wrench_frame_warning


def test_a_cart_frame_reading_that_drops_but_still_misfits_is_warned_not_refused():
    # MuJoCo load-change seed 2202 (50.6 -> 79.3 kg put in mid-log): 9.81x the noise as logged, 6.4x read in {b}
    check_wrench_frame("log", (9.81, 5.0), (6.4, 11.94))
    assert "cart frame {b}" in wrench_frame_warning((9.81, 5.0), (6.4, 11.94), 100.0)


@pytest.mark.parametrize("other", [0.76, FIT_RATIO])
def test_a_cart_frame_reading_that_fits_is_refused(other):
    # rigid_sim seed 19 with (fx, fy) in {b}: 5.5x as logged, 0.76x read in {b}
    with pytest.raises(UnitsError, match=r"cart frame \{b\}"):
        check_wrench_frame("log", (5.5, 1.0), (other, 35.88))
