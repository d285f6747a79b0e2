"""What a load-change log lets any estimator date and weigh (issue 27's criterion: onset within 1 s, after-mass
within 5 %), with the truth known and before any noise lowers it.

- the stretch around the true change that the motion cannot date (:func:`cart.segments.information_stretch_of`
  on the offline regression of the whole log): a change that may lie anywhere in it is dated within 1 s with
  probability min(1, 2 / width) (:func:`p_date`);
- the after-side's mass std (:func:`cart.identify.identify` on the log from one cut-off period after the true
  change): an unbiased estimate with that std is within 5 % with probability erf(5 / (std sqrt 2))
  (:func:`p_mass`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cart.logs import CartLog

#: Half of it either side of a change is issue 27's tolerance: a stretch wider than this cannot be dated within
#: 1 s by its middle.
WIDE_STRETCH_S = 2.0
#: Issue 27's after-mass tolerance, % of the true mass after the change.
MASS_TOLERANCE_PCT = 5.0


def p_date(width: float) -> float:
    """Return the chance that a change anywhere in a stretch of ``width`` s is dated within 1 s by its middle."""
    return min(1.0, WIDE_STRETCH_S / width) if width > 0.0 else 1.0


def p_mass(std_pct: float) -> float:
    """Return the chance that an unbiased mass estimate with std ``std_pct`` (% of the truth) is within 5 %."""
    return math.erf(MASS_TOLERANCE_PCT / (std_pct * math.sqrt(2.0))) if std_pct > 0.0 else 1.0


def stretch_row(log: CartLog, t_change: float) -> dict[str, Any]:
    """Return the undatable stretch around ``t_change`` (s from the change), its width and :func:`p_date`."""
    from cart import segments
    from cart.identify import identify

    lo, hi = segments.information_stretch_of(identify(log), t_change)
    width = hi - lo
    return {"t_change": t_change, "stretch": (lo - t_change, hi - t_change), "width": width, "p_date": p_date(width)}


def after_std_pct(log: CartLog, t_change: float, m_after: float) -> float:
    """Return the std (% of ``m_after``) of the mass identified on ``log`` from one cut-off period after
    ``t_change`` (as ``cartpush estimate`` identifies the side after a change)."""
    from cart import segments
    from cart.identify import identify

    guard = 1.0 / identify(log).cutoff_hz
    after = identify(segments.slice_log(log, t_change + guard, float(log.t[-1])))
    return 100.0 * float(after.std["mass"]) / m_after


def share(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Return the sum and mean of the rows' ``p_date`` (and of ``p_date * p_mass`` where rows have ``p_mass``) and
    the seeds whose stretch is wider than :data:`WIDE_STRETCH_S`."""
    pd = np.array([r["p_date"] for r in rows])
    out: dict[str, Any] = {
        "logs": len(rows),
        "expected_dated": float(pd.sum()),
        "share": float(pd.mean()) if rows else math.nan,
        "wider_than_2s": [r.get("seed") for r in rows if r["width"] > WIDE_STRETCH_S],
    }
    if rows and all("p_mass" in r for r in rows):
        both = pd * np.array([r["p_mass"] for r in rows])
        out.update(expected_dated_and_weighed=float(both.sum()), share_dated_and_weighed=float(both.mean()))
    return out
