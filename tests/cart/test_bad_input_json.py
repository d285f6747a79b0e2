"""Issue 14, class 5: strict JSON (null where a number is undefined) — cart.jsonout.dumps_strict."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cart.jsonout import dumps_strict, to_strict


def _refuse(name):
    raise ValueError(name)


def test_non_finite_values_become_null_everywhere():
    obj = {
        "a": math.nan,
        "b": [math.inf, -math.inf, 1.5],
        "c": (np.float64("nan"), np.float32(2.0)),
        "d": np.array([[1.0, np.nan], [np.inf, 3.0]]),
        "e": {"f": np.int64(3), "g": np.bool_(True)},
        "h": None,
        "i": "NaN",
    }
    text = dumps_strict(obj)
    back = json.loads(text, parse_constant=_refuse)
    assert back == {
        "a": None,
        "b": [None, None, 1.5],
        "c": [None, 2.0],
        "d": [[1.0, None], [None, 3.0]],
        "e": {"f": 3, "g": True},
        "h": None,
        "i": "NaN",
    }


def test_plain_json_would_not_be_strict_and_allow_nan_stays_off():
    assert "NaN" in json.dumps({"x": math.nan})
    assert to_strict(math.nan) is None
    with pytest.raises(TypeError):
        dumps_strict(object())  # not JSON-serialisable: a bug, not silently stringified
