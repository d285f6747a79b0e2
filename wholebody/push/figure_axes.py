"""Axes helpers of a run's figures: y ranges a short spike does not set, clipping said on the chart, times marked.

`robust_ylim` sets an axis's y range from the samples that describe the run (e.g. before the cart was lost): a
high percentile widened by a share of the spread, never beyond the data, so a start transient or the moment of a
loss does not flatten the rest; what the range cuts off is named on the chart ("clipped: max 3346 mm at t =
29.9 s"). `mark_time` draws a labelled vertical line. Nothing here selects or touches a Matplotlib backend.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

#: resolution of the saved PNG figures, dots per inch
FIGURE_DPI = 150
#: the y range spans these percentiles of the samples that set it ...
RANGE_PERCENTILES = (1.0, 99.0)
#: ... widened on each side by this share of their spread, never beyond the samples' own extremes
RANGE_WIDEN = 1.0
#: the range's margin, as a share of its span
RANGE_PAD = 0.05


@dataclass(frozen=True)
class Trace:
    """A plotted series: times `t`, values `y`, and `keep`, the samples that set the y range (boolean, like t)."""

    t: np.ndarray
    y: np.ndarray
    keep: np.ndarray


def _kept_values(traces: Sequence[Trace]) -> np.ndarray:
    """Return the finite kept samples of the traces (every finite sample when none is kept)."""
    kept = np.concatenate([np.asarray(tr.y, float)[np.asarray(tr.keep, bool)] for tr in traces])
    kept = kept[np.isfinite(kept)]
    if kept.size:
        return kept
    every = np.concatenate([np.asarray(tr.y, float) for tr in traces])
    return every[np.isfinite(every)]


def robust_range(traces: Sequence[Trace], zero_bottom: bool = False, at_least: float = 0.0) -> tuple[float, float]:
    """Return the (low, high) y range of the traces' kept samples (module doc), padded; from 0 with `zero_bottom`
    (a quantity never below it), up to at least `at_least`."""
    v = _kept_values(traces)
    if not v.size:
        return 0.0, max(1.0, at_least)
    p_lo, p_hi = np.percentile(v, RANGE_PERCENTILES)
    widen = RANGE_WIDEN * (p_hi - p_lo)
    lo, hi = max(float(v.min()), p_lo - widen), max(min(float(v.max()), p_hi + widen), at_least)
    lo = 0.0 if zero_bottom else lo
    pad = max(RANGE_PAD * (hi - lo), 0.02 * max(abs(lo), abs(hi)), 1e-3)
    return (lo if zero_bottom else lo - pad), hi + pad


def _number(v: float) -> str:
    """Return a value for a chart note: whole numbers from 100, else 3 significant digits."""
    return f"{v:.0f}" if abs(v) >= 100 else f"{v:.3g}"


def _extreme(traces: Sequence[Trace], sign: float) -> tuple[float, float] | None:
    """Return (value, t) of the traces' largest (`sign` 1) or smallest (-1) finite sample, None when there is none."""
    best = None
    for tr in traces:
        y = sign * np.asarray(tr.y, float)
        if np.any(np.isfinite(y)):
            k = int(np.nanargmax(y))
            if best is None or y[k] > sign * best[0]:
                best = (sign * float(y[k]), float(np.asarray(tr.t, float)[k]))
    return best


def clipped_note(traces: Sequence[Trace], lo: float, hi: float, unit: str) -> str:
    """Return what the range (lo, hi) cuts off the traces: 'clipped: max X unit at t = T s' (and/or min), or ''."""
    lines = []
    for name, sign, limit in (("max", 1.0, hi), ("min", -1.0, lo)):
        found = _extreme(traces, sign)
        if found is not None and sign * found[0] > sign * limit:
            lines.append(f"clipped: {name} {_number(found[0])} {unit} at t = {found[1]:.1f} s")
    return "\n".join(lines)


def robust_ylim(ax: Any, traces: Sequence[Trace], unit: str, zero_bottom: bool = False, at_least: float = 0.0) -> str:
    """Set `ax`'s y range by `robust_range` and write what it clips in the axes' top left corner; return the note."""
    lo, hi = robust_range(traces, zero_bottom, at_least)
    ax.set_ylim(lo, hi)
    note = clipped_note(traces, lo, hi, unit)
    if note:
        ax.text(
            0.01,
            0.97,
            note,
            transform=ax.transAxes,
            ha="left",
            va="top",
            fontsize=7,
            color="0.15",
            zorder=6,
            bbox={"boxstyle": "round,pad=0.2", "fc": "w", "ec": "0.6", "alpha": 0.85},
        )
    return note


#: the look of a time mark's label (`mark_time`)
MARK_LABEL = {
    "va": "top",
    "fontsize": 7,
    "zorder": 6,
    "bbox": {"boxstyle": "square,pad=0.1", "fc": "w", "ec": "none", "alpha": 0.75},
}


def mark_time(ax: Any, t: float, text: str, colour: str = "r", slot: int = 0) -> None:
    """Draw a vertical line at time `t` with `text` near the axes' top (lower for each later `slot`), on the side of
    the line facing the middle of the time axis."""
    ax.axvline(t, color=colour, lw=1.2, zorder=5)
    left, right = ax.get_xlim()
    side = "left" if t < 0.5 * (left + right) else "right"
    y = 0.97 - 0.09 * slot
    ax.text(t, y, f" {text} ", transform=ax.get_xaxis_transform(), ha=side, color=colour, **MARK_LABEL)
