"""Issue 30 item 5: units a log declares in its metadata, and units diagnose must see as estimate does.

A force scale is invisible in the data: forces in lbf give every parameter 4.45x too small and the model
fits as well (exit 0 with 11.2 kg for a 50 kg cart). A ``# ...unit...:`` metadata line that names a non-SI
unit is the log's own word on it: refused with the conversion. ``diagnose`` read positions in millimetres
as a cart and named effects (it never checked units).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cart.diagnose import diagnose
from cart.estimate_report import estimate_log
from cart.logs import CartLog
from cart.units import UnitsError, check_declared_units
from studies.testbeds.hidden_effects import random_case


def _log() -> CartLog:
    return random_case(None, np.random.default_rng(11), duration=20.0).measured


@pytest.mark.parametrize(
    "key, value, word",
    [
        ("units", "t s, x y m, theta rad, fx fy lbf, tau lbf ft", "lbf"),
        ("force_unit", "kgf", "kgf"),
        ("Units", "x, y in mm", "mm"),
        ("theta_units", "degrees", "degrees"),
        ("time_unit", "ms", "ms"),
    ],
)
def test_a_declared_non_si_unit_is_refused_with_the_factor(key, value, word):
    with pytest.raises(UnitsError, match=f"in {word}; .*multiply"):
        check_declared_units({key: value}, "log.csv")


@pytest.mark.parametrize(
    "meta", [{"units": "SI"}, {"units": "t s, x y m, theta rad, fx fy N, tau N m"}, {"note": "lbf sensor, converted"}]
)
def test_si_or_free_text_metadata_passes(meta):
    check_declared_units(meta, "log.csv")


def test_estimate_refuses_forces_declared_in_lbf():
    log = _log()
    lbf = replace(log, gamma=log.gamma / 4.4482216, metadata={"units": "force lbf, torque lbf ft"})
    with pytest.raises(UnitsError, match="lbf"):
        estimate_log(lbf)


def test_diagnose_refuses_positions_in_millimetres_as_estimate_does():
    log = _log()
    mm = replace(log, q=log.q * [1000.0, 1000.0, 1.0], qd=None if log.qd is None else log.qd * [1000.0, 1000.0, 1.0])
    with pytest.raises(UnitsError, match="millimetres"):
        diagnose(mm)


def test_a_header_in_capitals_with_units_in_brackets_is_read_and_its_units_checked(tmp_path):
    from cart.logs import read_log, write_log

    log = _log()
    path = tmp_path / "base.csv"
    write_log(path, replace(log, qd=None))
    lines = path.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("t,"))
    lines[head] = "T [s],X [m],Y [m],Theta (rad),FX [N],FY [N],Tau [N m]"
    lines.insert(head + 50, "")  # a blank line and a comment among the rows are not rows
    lines.insert(head + 80, "# lap: 2")
    (tmp_path / "caps.csv").write_text("\n".join(lines) + "\n")
    got = read_log(tmp_path / "caps.csv")
    assert np.array_equal(got.t, log.t) and any("comment line" in w for w in got.warnings)
    lines[head] = "T [s],X [mm],Y [mm],Theta (rad),FX [N],FY [N],Tau [N m]"
    (tmp_path / "mm.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(UnitsError, match="length in mm"):
        estimate_log(str(tmp_path / "mm.csv"))


def test_time_in_minutes_and_positions_in_inches_are_named():
    log = replace(_log(), qd=None)
    with pytest.raises(UnitsError, match="minutes; multiply t by 60"):
        estimate_log(replace(log, t=log.t / 60.0))
    with pytest.raises(UnitsError, match="inches"):
        estimate_log(replace(log, q=log.q * [39.37, 39.37, 1.0]))


def test_a_flipped_wrench_sign_is_refused_by_estimate_and_diagnose():
    from cart.errors import CartError

    log = replace(_log(), qd=None)
    flipped = replace(log, gamma=-log.gamma)
    with pytest.raises(CartError, match="sign looks flipped"):
        estimate_log(flipped)
    with pytest.raises(CartError, match="sign looks flipped"):
        diagnose(flipped)


def test_units_in_the_header_row_are_named_as_the_header_not_as_a_metadata_line():
    """The refusal quoted a "# units (header): ..." line the file does not hold (an outside tester's log whose
    header reads ``x [mm]``)."""
    with pytest.raises(UnitsError, match=r"the header row's units \(x: mm\) declare length in mm.*name the columns"):
        check_declared_units({"units (header)": "x: mm"}, "log.csv")
