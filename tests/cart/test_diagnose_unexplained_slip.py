"""The diagnosis warns when {b} slides sideways and lateral_slip's model does not describe it (issue 30, item 7)."""

from __future__ import annotations

import math

from cart.diagnose_checks import SLIP_RATIO, unexplained_slip


def test_a_broken_no_slip_constraint_left_unnamed_is_a_warning_with_its_ratio_and_evidence() -> None:
    note = unexplained_slip(17.3, [], -3.7)
    assert "17.3 x" in note
    assert "eq. 3" in note
    assert "Delta BIC -3.7" in note


def test_no_warning_when_lateral_slip_is_named_or_the_constraint_holds() -> None:
    assert unexplained_slip(17.3, ["coulomb_friction", "lateral_slip"], 39.8) == ""
    assert unexplained_slip(SLIP_RATIO, [], -3.7) == ""
    assert unexplained_slip(1.1, [], None) == ""
    assert unexplained_slip(math.nan, [], None) == ""


def test_an_unranked_lateral_slip_says_so() -> None:
    note = unexplained_slip(5.0, ["payload_change"], None)
    assert "not ranked" in note
