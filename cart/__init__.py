"""The cart alone (numpy/scipy only): dynamics, model, simulation, control, EKF, identification, logs, diagnosis.

The names below are loaded on first use, so ``import cart`` (and the CLI's start-up) stays cheap:

>>> from cart import CartParams, identify, read_log
>>> p = CartParams(20.0, 0.3, 0.15, 1.7, 4.0)
>>> p.m
20.0

Every error derives from :class:`CartpushError` (``cart.errors``), the project's root exception.
"""

from __future__ import annotations

import importlib
from typing import Any

from cart.errors import CartError, CartpushError, LogFormatError, NumericalError, ParameterError

#: public name -> module that defines it
_LAZY = {
    "CartParams": "cart.params",
    "CartLog": "cart.logs",
    "read_log": "cart.logs",
    "write_log": "cart.logs",
    "Identification": "cart.identify",
    "IdentifiabilityError": "cart.identify",
    "identify": "cart.identify",
    "CartEKF": "cart.ekf",
    "EKFConfig": "cart.ekf",
    "estimate_from_log": "cart.ekf",
    "DiagnoseError": "cart.errors",
    "diagnose": "cart.diagnose",
    "MeasurementNoise": "cart.simulate",
    "simulate": "cart.simulate",
    "UnicycleTrajectory": "cart.trajectories",
    "trajectory_1": "cart.trajectories",
    "trajectory_2": "cart.trajectories",
    "CONTROLLERS": "cart.control",
    "ControllerName": "cart.control",
    "make_controller": "cart.control",
    "forward_dynamics": "cart.dynamics",
    "inverse_dynamics": "cart.dynamics",
    "regressor": "cart.dynamics",
    "dumps_strict": "cart.jsonout",
}

__all__ = [
    "CONTROLLERS",
    "CartEKF",
    "CartError",
    "CartLog",
    "CartParams",
    "CartpushError",
    "ControllerName",
    "DiagnoseError",
    "EKFConfig",
    "IdentifiabilityError",
    "Identification",
    "LogFormatError",
    "MeasurementNoise",
    "NumericalError",
    "ParameterError",
    "UnicycleTrajectory",
    "diagnose",
    "dumps_strict",
    "estimate_from_log",
    "forward_dynamics",
    "identify",
    "inverse_dynamics",
    "make_controller",
    "read_log",
    "regressor",
    "simulate",
    "trajectory_1",
    "trajectory_2",
    "write_log",
]


def __getattr__(name: str) -> Any:
    """Import the module that defines `name` on first use (PEP 562)."""
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'cart' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
