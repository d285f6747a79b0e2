"""Issue 30, diagnose on effect-free multi-rate logs: the logging's own timing is not a time_delay.

A table with a row per motion-capture sample and the F/T averaged over the interval before it carries the
wrench half an interval early (4 ms at 120 Hz). On a long, well-excited log the time_delay candidate
fits that shift significantly (Delta BIC 22.6 for a 7.9 +- 1.1 ms delay on the log below, written by
the project's independent generator with fresh seeds); a delay within one sample interval is the
logging's timing, not an effect of the set-up.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cart.diagnose import _logging_timing, diagnose
from studies.testbeds.hidden_effects import multirate_log


@dataclass
class _Fit:
    effects: list


@dataclass
class _FakeTrial:
    fit: _Fit
    nl_std: list


def _trial(delay: float, std: float) -> _FakeTrial:
    return _FakeTrial(_Fit([("time_delay", (delay,))]), [std])


def test_a_delay_within_one_sample_interval_is_the_loggings_timing():
    assert "within one sample interval" in _logging_timing(_trial(0.0079, 0.0011), 1 / 120)  # type: ignore[arg-type]
    assert "within one sample interval" in _logging_timing(_trial(-0.012, 0.003), 0.01)  # type: ignore[arg-type]
    assert _logging_timing(_trial(0.05, 0.004), 1 / 120) == ""  # type: ignore[arg-type]
    assert _logging_timing(_trial(-0.05, 0.01), 0.02) == ""  # type: ignore[arg-type]


def test_an_effect_free_mocap_rows_table_names_nothing():
    rng = np.random.default_rng(31001)
    multirate_log(rng, "held_pose")  # the scenario writer draws the held-pose twin first
    log, _ = multirate_log(rng, "mocap_rows")
    rep = diagnose(log)
    assert [e.name for e in rep.effects] == []
