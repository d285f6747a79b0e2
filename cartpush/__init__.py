"""cartpush: mobile manipulators that push passive, nonholonomic carts (the curated API).

The product on top of the library packages: this module re-exports what a user reaches for
(loaded on first use, so ``import cartpush`` stays cheap); ``cartpush.cli`` is the command line,
``cartpush.batch`` runs a job over many logs or robots (local processes or Ray), ``cartpush.ros``
reads ROS 1/ROS 2 bags and MCAP files as cart logs. Layers point down only:
``cartpush`` -> ``wholebody`` -> ``robots``, ``cart``.

>>> import cartpush
>>> cartpush.CartParams(20.0, 0.3, 0.15, 1.7, 4.0).m
20.0
"""

from __future__ import annotations

import importlib
from typing import Any

from cart.errors import CartpushError

#: public name -> module that defines it
_LAZY = {
    **{n: "cart" for n in ("CartParams", "CartLog", "read_log", "write_log", "identify", "diagnose", "CartEKF")},
    **{n: "cart" for n in ("estimate_from_log", "simulate", "trajectory_1", "trajectory_2", "UnicycleTrajectory")},
    "load_robot": "robots",
    **{n: "wholebody" for n in ("WholeBody", "wholebody_for", "ResolvedRateController", "ControllerConfig")},
    **{n: "wholebody" for n in ("WrenchAllocator", "allocate", "optimal_contact_points", "HandleSegment")},
    **{n: "wholebody" for n in ("PushConfig", "PushResult", "run_push", "Scene")},
    **{n: "wholebody.push" for n in ("PushController", "KinematicPlant", "Measurement", "RobotCommand")},
}

__all__ = ["CartpushError", *sorted(_LAZY)]


def __getattr__(name: str) -> Any:
    """Import the module that defines `name` on first use (PEP 562)."""
    if name in _LAZY:
        module = importlib.import_module(_LAZY[name])
        value = getattr(module, "load" if name == "load_robot" else name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'cartpush' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
