"""Issue 30 item 7: no effect named on effect-free multi-rate logs whose cart rests for seconds.

Seed 9700's ``held_pose00`` and ``held_pose03`` of ``studies.diagnose_study --write-scenarios`` (rebuilt here
from their seeds): F/T at 500 Hz with AR(1) noise (lag-10 correlation 0.6-0.8) written beside a motion-capture
pose held between its 120 Hz samples; the cart rests (or turns in place) 18 % and 32 % of the time. The
casters' set-valued hold at rest absorbed the noise's slow part there, and ``caster_swivel`` was named with
Delta BIC 11.9 and 22.3 (-3.4 and -11.6 once a hold must exceed twice the std the log's own AR(1) noise gives
the force's 0.2 s local mean).
"""

from __future__ import annotations

import numpy as np
import pytest

from cart.diagnose import diagnose
from studies.testbeds.hidden_effects import multirate_log


@pytest.mark.parametrize("k", [0, 3])
def test_an_effect_free_held_pose_log_names_no_caster_swivel(k):
    log, _ = multirate_log(np.random.default_rng(9700 + k), "held_pose")
    rep = diagnose(log)
    assert "caster_swivel" not in rep.names, rep.summary()
    caster = [v for v in rep.not_named if v.name == "caster_swivel"]
    assert caster and caster[0].delta_bic < rep.threshold, rep.summary()
