"""A mass known only to more than 5 % (1 std) is said so in the estimate's warnings.

Light carts under heavy F/T noise (the h31 tester's 5-7 kg carts at 3.6-5 N): the mass came out 12-23 % off
with an honest std (4.01 +- 0.83 kg for 5.23) and no warning; the number alone reads as a few per cent.
"""

from __future__ import annotations

import json

import pytest

from cart.estimate_report import WEAK_MASS_STD, estimate_log
from cart.jsonout import dumps_strict
from studies.testbeds import log_recorders as lr
from studies.testbeds import rigid_sim


def _weak_notes(warnings) -> list[str]:
    """Return the warnings that say the mass is known only roughly."""
    return [w for w in warnings if w.startswith("the mass is known only to")]


@pytest.mark.parametrize("seed, rec_seed", [(506, 3), (101, 1)])
def test_the_warning_follows_the_mass_std(seed, rec_seed):
    # seed 506: a 7.9 kg cart, its mass std ~12 %; seed 101: a 114 kg cart, ~1.6 %
    rec = lr.record(rigid_sim.random_case(seed, duration=40.0 if seed == 101 else 45.0), seed=rec_seed)
    r = estimate_log(lr.mocap_rows_table(rec))
    share = r.std["mass"] / r.params.m
    notes = _weak_notes(r.warnings)
    assert (len(notes) == 1) == (share > WEAK_MASS_STD), (share, r.warnings)
    out = json.loads(dumps_strict(r.to_dict()))
    assert _weak_notes(out["warnings"]) == notes
    if seed == 506:
        assert share > 2 * WEAK_MASS_STD and r.model_fits  # far from the rule's edge: this log must warn
        assert f"+-{100 * share:.0f} %" in notes[0] and "little forward acceleration for the F/T noise" in notes[0]
    else:
        assert share < 0.5 * WEAK_MASS_STD and not notes


def test_the_note_replaces_the_fit_s_weakly_excited_mass_and_names_a_misfit():
    from cart.estimate_report import _final_notes
    from cart.params import CartParams

    p = CartParams(2.0, 0.0, 0.0, 0.5, 1.0)
    std = {"mass": 1.2, "com": [0.01, 0.01], "inertia": 0.01}
    fit_note = "mass weakly excited (std 1.2 kg for 2 kg): little forward acceleration above the noise"
    notes = _final_notes([fit_note, "other"], p, std, {}, fits=False)
    assert notes[0] == "other" and len(notes) == 2 and notes[1].startswith("the mass is known only to +-60 %")
    assert "misfit" in notes[1]
    assert _final_notes([fit_note], p, {**std, "mass": 0.05}, {}, fits=True) == (fit_note,)  # 2.5 %: no note
