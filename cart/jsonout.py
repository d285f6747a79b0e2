"""Strict JSON output: NaN and +-Infinity become ``null`` (docs/architecture.md: "JSON is strict")."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np


def to_strict(obj: Any) -> Any:
    """Return a copy of ``obj`` with plain Python types and every non-finite float replaced by None.

    Handles nested dicts, lists and tuples, numpy scalars and arrays, and objects
    with a ``to_dict()`` / ``as_dict()`` method; other values pass through.
    """
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, int):
        return obj
    if isinstance(obj, np.generic):
        return to_strict(obj.item())
    if isinstance(obj, np.ndarray):
        return to_strict(obj.tolist())
    if isinstance(obj, dict):
        return {
            str(k) if not isinstance(k, (str, int, float, bool)) and k is not None else k: to_strict(v)
            for k, v in obj.items()
        }
    if isinstance(obj, (list, tuple)):
        return [to_strict(v) for v in obj]
    for name in ("to_dict", "as_dict"):
        method = getattr(obj, name, None)
        if callable(method):
            return to_strict(method())
    if hasattr(obj, "__fspath__"):
        return str(obj)
    return obj


def dumps_strict(obj: Any, **kwargs: Any) -> str:
    """Return strict JSON text of ``obj``: NaN / +-Infinity (also in numpy values) become null.

    ``allow_nan=False`` makes ``json`` itself refuse any non-finite number that slipped through.
    """
    kwargs.setdefault("allow_nan", False)
    return json.dumps(to_strict(obj), **kwargs)
