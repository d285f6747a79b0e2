"""Issue 30: a log with too few independent rows is refused with the fix that fits it: longer stretches without
gaps when gaps (or the ends) took the rows, a push with more motion when the rows are there but band-limited."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from cart.identify import IdentifiabilityError, _check_independent_rows


def _reg(n_grid: int, n_kept: int, n_params: int = 6) -> SimpleNamespace:
    keep = np.zeros(n_grid, dtype=bool)
    keep[:n_kept] = True
    return SimpleNamespace(y=np.zeros(n_kept), x=np.zeros((n_kept, n_params)), keep=keep)


@pytest.mark.parametrize(
    ("n_grid", "hint"),
    [(100, "push longer, with more speed changes and turns"), (1000, "log longer stretches without gaps")],
)
def test_the_refusal_names_the_fix_that_fits_the_log(n_grid, hint):
    log = SimpleNamespace(source="still.csv")
    with pytest.raises(IdentifiabilityError, match="nothing can be identified") as err:
        _check_independent_rows(log, _reg(n_grid, 90), lag=100, fc_dt=(0.3, 0.01))
    assert hint in str(err.value)


def test_enough_independent_rows_pass():
    _check_independent_rows(SimpleNamespace(source="ok.csv"), _reg(1000, 1000), lag=10, fc_dt=(5.0, 0.01))
