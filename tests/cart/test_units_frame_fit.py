"""The cart-frame refusal needs the {b} reading to fit (cart.units.check_wrench_frame), as the torque-origin one."""

from __future__ import annotations

import pytest

from cart.identify import FIT_RATIO
from cart.units import UnitsError, check_wrench_frame, wrench_frame_warning


def test_a_cart_frame_reading_that_drops_but_still_misfits_is_warned_not_refused():
    # MuJoCo load-change seed 2202 (50.6 -> 79.3 kg put in mid-log): 9.81x the noise as logged, 6.4x read in {b}
    check_wrench_frame("log", (9.81, 5.0), (6.4, 11.94, 6.0))
    assert "cart frame {b}" in wrench_frame_warning((9.81, 5.0), (6.4, 11.94, 6.0), 100.0)


@pytest.mark.parametrize("other", [0.76, FIT_RATIO])
def test_a_cart_frame_reading_that_fits_is_refused(other):
    # rigid_sim seed 19 with (fx, fy) in {b}: 5.5x as logged, 0.76x read in {b}
    with pytest.raises(UnitsError, match=r"cart frame \{b\}"):
        check_wrench_frame("log", (5.5, 1.0), (other, 35.88, other))


def test_under_slow_noise_a_cart_frame_reading_that_fits_as_slow_noise_and_drops_fourfold_is_refused():
    # an outside tester's AR(1)-noise cart written in {b}: 5.09x the noise as logged, accepted as slow sensor noise;
    # read in {b} 1.63x (above FIT_RATIO), 0.9x above the slow band, the yaw row fitting
    with pytest.raises(UnitsError, match=r"cart frame \{b\}"):
        check_wrench_frame("log", (5.09, 0.8), (1.63, 37.03, 0.9))
    # a threefold drop only: not enough
    check_wrench_frame("log", (5.09, 0.8), (3.0, 37.03, 0.9))
    # the {b} reading misfits above the slow band too
    check_wrench_frame("log", (5.09, 0.8), (1.63, 37.03, 1.9))


def test_a_yaw_misfit_keeps_the_slow_route_from_refusing():
    # coloured-noise seed 5101, a random-walk F/T offset on a 17.1 kg cart, written in {s}: 6.43x and 4.38x as
    # logged, 2.55x read in {b} (1.56x above the slow band): the torque, the same in both readings, misfits
    check_wrench_frame("log", (6.43, 4.38), (2.55, 8.34, 1.56))
