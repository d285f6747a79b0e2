"""A push run's page charts: the cart's estimated mass and CoM with their band against the truth, over time.

`estimate_charts` adds to a `Scene` one chart per parameter (`Scene.add_chart`, bottom right of the page): the
estimate the controller used at each period (``PushResult.phi_hat``), its +-1-sigma band (``param_std``: the mass's,
and each CoM axis its own), the truth it is judged against (``config.true_params``: on the MuJoCo plant
the cart's effective mass and its CoM read from the engine, `wholebody.push.plants.plant_truth`), the load changes
the estimator found (onset and detection), its run-off flags, and when the cart was lost. A cursor follows the
page's time.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from wholebody.viz.scene import Scene

#: the charts' y range leaves out the estimate's first seconds (the figures' "after 5 s" metrics do the same)
SETTLE_S = 5.0


def estimate_marks(result: Any) -> list[tuple[float, str]]:
    """Return the chart marks of a run: each load the plant put in or took out (``load_changes_true``), each load
    change the estimator found (onset and detection), run-off flags, the loss of the cart."""
    report = result.estimator_report or {}
    marks = [(c["t_applied"], "made") for c in getattr(result, "load_changes_true", ()) or ()]
    marks += [(c["t_change"], "change") for c in report.get("load_changes") or ()]
    marks += [(c["t_detected"], "detected") for c in report.get("load_changes") or ()]
    marks += [(f["t"], "runoff") for f in report.get("runoff_flags") or ()]
    if result.metrics.tracking_lost_at_s is not None:
        marks.append((result.metrics.tracking_lost_at_s, "lost"))
    return marks


def estimate_charts(scene: Scene, result: Any) -> None:
    """Add the run's mass, CoM x and CoM y charts to the page (see the module doc)."""
    p, phi, t = _truth(result), result.phi_hat, result.t
    m = np.where(np.abs(phi[:, 0]) > 1e-9, phi[:, 0], np.nan)
    std = result.param_std if result.config.estimation and result.param_std is not None else None
    name = "estimate" if result.config.estimation else "fixed guess (no estimation)"
    marks = estimate_marks(result)
    lost = result.metrics.tracking_lost_at_s
    until = math.inf if lost is None else float(lost)
    series = (
        (f"mass, {name}", "kg", phi[:, 0], None if std is None else std[:, 0], p[:, 0]),
        (
            f"CoM x in {{b}}, {name}",
            "cm",
            100 * phi[:, 1] / m,
            None if std is None else 100 * _axis(std, 0),
            100 * p[:, 1],
        ),
        (
            f"CoM y in {{b}}, {name}",
            "cm",
            100 * phi[:, 2] / m,
            None if std is None else 100 * _axis(std, 1),
            100 * p[:, 2],
        ),
    )
    for title, unit, estimate, band, truth in series:
        scene.add_chart(title, unit, t, estimate, band, truth, marks, settle=SETTLE_S, until=until)


def _axis(std: np.ndarray, axis: int) -> np.ndarray:
    """Return the CoM's 1-sigma along x (0) or y (1) from `PushResult.param_std` (m); the norm over both for a
    result that records only it (two columns)."""
    return std[:, 2 + axis] if std.shape[1] >= 4 else std[:, 1]


def _truth(result: Any) -> np.ndarray:
    """Return (N, >= 3) m, dx, dy of the truth at each sample: ``result.truth()`` (it steps at each load change the
    plant made), or ``config.true_params`` throughout for a result without it."""
    truth = getattr(result, "truth", None)
    if callable(truth):
        return np.asarray(truth(), dtype=float)
    p = result.config.true_params
    return np.tile([p.m, p.dx, p.dy], (len(result.t), 1))
