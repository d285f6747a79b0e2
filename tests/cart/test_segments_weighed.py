"""A split is kept only when the log weighs both of its sides (cart.segments._weighed)."""

from __future__ import annotations

import pathlib
import sys
from dataclasses import replace

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # `studies` is not an installed package
    sys.path.insert(0, str(ROOT))

import cart.identify  # noqa: E402
from cart import segments  # noqa: E402
from studies.testbeds import rigid_sim  # noqa: E402
from studies.testbeds.log_recorders import load_change_case  # noqa: E402


@pytest.mark.parametrize(
    "mass_over_std, n_segments", [(0.9 * segments.IDENTIFIED_Z, 1), (1.1 * segments.IDENTIFIED_Z, 2)]
)
def test_a_side_whose_own_fit_does_not_weigh_it_is_no_segment(monkeypatch, mass_over_std, n_segments):
    # simulator 3010 (11.4 -> 6.9 kg) splits into two segments; the side after the change identified on its own
    # with a mass std of 1 / mass_over_std of its mass: under IDENTIFIED_Z the split is not kept
    case = load_change_case(3010)
    log, _ = rigid_sim.simulate(case)
    whole = cart.identify.identify(log)
    real = cart.identify.identify

    def vague_after(part, **kw):
        res = real(part, **kw)
        if part.t[0] > float(case.load_time or 0.0) - 1.0:
            return replace(res, std={**res.std, "mass": res.params.m / mass_over_std})
        return res

    monkeypatch.setattr(cart.identify, "identify", vague_after)
    segs, _ = segments.find_segments(log, None, whole)
    assert len(segs) == n_segments
