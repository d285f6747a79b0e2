"""A log whose wrench is zero in every row (no F/T data recorded): one line naming it, from estimate and diagnose.

Before: `estimate` read the zeros as missing F/T samples and said "5921 pose and 1 wrench samples are too few";
`diagnose` said "the model fit broke down numerically (Eigenvalues did not converge)".
"""

from __future__ import annotations

import numpy as np
import pytest

from cart.diagnose import diagnose
from cart.errors import CartError, DiagnoseError
from cart.estimate_report import estimate_log
from cart.logs import CartLog


def _zero_wrench_log() -> CartLog:
    t = np.arange(4000) / 100.0
    q = np.column_stack([0.3 * t, 0.1 * np.sin(0.2 * t), 0.05 * np.sin(0.3 * t)])
    q = q + np.random.default_rng(60103).normal(0.0, 5e-4, q.shape)
    return CartLog(t=t, q=q, gamma=np.zeros((len(t), 3)))


def test_estimate_names_a_zero_wrench():
    with pytest.raises(CartError, match="the wrench is zero throughout"):
        estimate_log(_zero_wrench_log())


def test_diagnose_names_a_zero_wrench():
    with pytest.raises(DiagnoseError, match="the wrench is zero throughout"):
        diagnose(_zero_wrench_log())
