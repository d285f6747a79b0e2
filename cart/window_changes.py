"""Load changes found online: the offline segment search run on a sliding window of the loop's own log.

The push loop sees the cart's pose, velocity and the wrench held over each period; this module keeps them
(:class:`LogWindow`) and every ``every_s`` seconds runs the offline machinery of ``cartpush estimate`` on the
last ``window_s`` seconds since the last change: :func:`cart.identify.identify` (the zero-phase filtered
regression, paper eq. 4 with the wrench as its output) and :func:`cart.segments.find_segments` (the split of
least residual, with the momentum exchange of a load put in at rest, kept when the two sides' masses differ
by ``cart.segments.CHANGE_Z`` combined std). A split kept at two checks in a row (the second with ``every_s``
more data after it: the window's many overlapping tests each risk a false alarm the offline search, run once on a
log, does not) is a load change: its onset is the split time,
which lies seconds in the past (each side needs ``cart.segments.MIN_SEGMENT_S`` of data), and the fit of
the window after it (mass, CoM, inertia, damping and their std) is what the online filter restarts from
(:meth:`cart.online_estimator.OnlineLSEstimator`). The segment search is the offline one, not a copy: its
physics and thresholds are those of ``cartpush estimate``. A refit costs one ``identify`` and one split
search on the window (tenths of a second on a 30 s window at 100 Hz; ``benchmarks/bench_online.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from cart.logs import CartLog
from cart.params import CartParams

if TYPE_CHECKING:
    from cart.identify import Identification


@dataclass(frozen=True)
class WindowChange:
    """A load change found on the window: onset (s) and its [earliest, latest] stretch, the time it was found,
    the cart before and after (the two sides' fits) and the after side's physical std (``Identification.std``)."""

    t_change: float
    t_range: tuple[float, float]
    t_detected: float
    before: CartParams
    after: CartParams
    after_std: dict
    #: the onset was searched again on the window (:meth:`WindowChangeDetector._refine`) and replaced
    refined: bool = False


class LogWindow:
    """The loop's own log: times, poses, velocities and the wrench held from each time to the next."""

    def __init__(self, t0: float, z0: np.ndarray) -> None:
        self._t: list[float] = [float(t0)]
        self._z: list[np.ndarray] = [np.asarray(z0, dtype=float)[:6].copy()]
        self._g: list[np.ndarray] = []
        self._theta = float(self._z[0][2])

    def add(self, t: float, gamma: np.ndarray, z: np.ndarray) -> None:
        """Add one period: ``gamma`` held since the last time, ``z`` (pose, velocity) at ``t``.

        The heading is unwrapped (the logs' convention, :class:`cart.logs.CartLog`).
        """
        row = np.asarray(z, dtype=float)[:6].copy()
        self._theta += (float(row[2]) - self._theta + math.pi) % (2.0 * math.pi) - math.pi
        row[2] = self._theta
        self._g.append(np.asarray(gamma, dtype=float).copy())
        self._t.append(float(t))
        self._z.append(row)

    def drop_before(self, t: float) -> None:
        """Forget the rows before ``t`` (the window never looks further back)."""
        i = int(np.searchsorted(np.asarray(self._t), t, side="left"))
        i = min(i, len(self._g))
        if i > 0:
            del self._t[:i], self._z[:i], self._g[:i]

    def log(self, t0: float) -> CartLog:
        """Return the rows from ``t0`` on that have their wrench, as a :class:`cart.logs.CartLog`."""
        n = len(self._g)
        t = np.asarray(self._t[:n])
        k = int(np.searchsorted(t, t0, side="left"))
        z = np.asarray(self._z[k:n])
        return CartLog(t=t[k:], q=z[:, :3], gamma=np.asarray(self._g[k:n]), qd=z[:, 3:6], source="online window")

    @property
    def t_last(self) -> float:
        """Return the time of the last row with its wrench (the window's end)."""
        return self._t[len(self._g) - 1] if self._g else self._t[0]


class WindowChangeDetector:
    """Every ``every_s`` s, the offline segment search on the last ``window_s`` s since the last change.

    ``t0``, ``z0``: the first time and state (pose, velocity) of the loop's log. :meth:`add` stores each
    period, :meth:`check` runs the search when due and returns the change it finds (None otherwise);
    :attr:`fit` is the last window's fit once it lies wholly after the last change (the cart as it is now).
    """

    def __init__(self, t0: float, z0: np.ndarray, every_s: float = 2.0, window_s: float = 30.0) -> None:
        from cart.segments import MIN_SEGMENT_S

        self.every_s = float(every_s)
        self.window_s = max(float(window_s), 2.0 * MIN_SEGMENT_S)
        self.min_window_s = 2.0 * MIN_SEGMENT_S
        self.window = LogWindow(t0, z0)
        self.start = float(t0)
        self._next = float(t0) + self.min_window_s
        self.fit: Identification | None = None  # the last window's fit, wholly after the last change
        self.checks = 0
        self.changes: list[WindowChange] = []  # the changes found, each onset refined while data come in
        self._before = float(t0)  # start of the window the last change was found in
        self._refining = False  # whether the last change's onset is searched again
        self._sighted: WindowChange | None = None  # a change the last check found, not yet found again
        self._seen: tuple[WindowChange, int] | None = None  # the last split any check found, and that check's number

    def add_change(self, change: WindowChange, guard_s: float, dated: bool = False) -> int:
        """Register a change found by another test (the online GLR); return its index in :attr:`changes`.

        The window restarts ``guard_s`` after its onset, and unless ``dated`` (an onset known to the period: a
        velocity jump, or a GLR onset inside its buffer) the onset is searched again like the window's own
        (:meth:`_refine`), on the window from the last change (its start): the test that found it kept too little
        data to bound its onset (a lift-out during a long cruise shows at the next braking, seconds later).
        """
        self._refining, self._sighted = not dated, None
        self._before = self.start
        self.start = max(self.start, change.t_change + guard_s)
        self.fit = None
        self.changes.append(change)
        return len(self.changes) - 1

    def add(self, t: float, gamma: np.ndarray, z: np.ndarray) -> None:
        """Store one period of the loop's log (``gamma`` held since the last time, ``z`` at ``t``)."""
        self.window.add(t, gamma, z)

    def check(self) -> WindowChange | None:
        """Run the segment search on the window when due; return the change it keeps at two checks in a row (None:
        none, not due, or seen at this check only: :func:`_same_change`).

        The window is [max(start, end - window_s), end]; after a change, ``start`` moves to the change plus the
        segment search's guard (one period of the fit's cut-off: the zero-phase filter mixes the two sides).
        A window of at least ``MIN_SEGMENT_S`` is fitted (:attr:`fit`); one of twice that is also searched.
        """
        from cart.identify import IdentifiabilityError, identify
        from cart.segments import find_segments

        end = self.window.t_last
        if end < self._next:
            return None
        self._next = end + self.every_s
        t0 = max(self.start, end - self.window_s)
        if end - t0 < 0.5 * self.min_window_s:
            return None
        refining = self._refining and end - self.changes[-1].t_detected <= 0.5 * self.window_s + self.every_s
        self.window.drop_before(min(t0, self._before) if refining else t0)
        log = self.window.log(t0)
        self.checks += 1
        try:
            res = identify(log)
            segs = find_segments(log, None, res)[0] if end - t0 >= self.min_window_s else []
        except (IdentifiabilityError, np.linalg.LinAlgError, ValueError):
            return None
        if len(segs) < 2:
            self.fit, self._sighted = res, None
            self._refine(end)
            return None
        change = _change(segs[0], segs[1], end)
        self._seen = (change, self.checks)
        sighted, self._sighted = self._sighted, change
        if sighted is None or not _same_change(sighted, change):
            return None  # seen once: kept only when the next check, with more data after it, finds it again
        self._sighted = None
        self._before, self.start, self.fit = t0, change.t_change + 1.0 / res.cutoff_hz, None
        self.changes.append(change)
        self._refining = True
        return change

    def recent_split(self, mass_change: float, before: float, checks: int = 2) -> WindowChange | None:
        """Return the split one of the last ``checks`` checks found after the last change (confirmed or not),
        when its mass moves the way ``mass_change`` (kg) does and its onset lies before ``before`` (s); else None.

        Another test's detection (the GLR's, on its 4 s buffer) takes this onset: the window's split is dated
        on up to ``window_s`` of data, the GLR's onset cannot lie before its buffer.
        """
        if self._seen is None or self.checks - self._seen[1] >= checks:
            return None
        seen = self._seen[0]
        moves = (seen.after.m - seen.before.m) * mass_change > 0.0
        after_last = not self.changes or seen.t_change > self.changes[-1].t_change
        return seen if moves and after_last and seen.t_change < before else None

    def _refine(self, end: float) -> None:
        """Search the last change's onset again, for ``window_s / 2`` s after it was found, on the window it was
        found in extended to now.

        When found, the side after it had ``MIN_SEGMENT_S`` of data; with more, the split's stretch of equal
        residual narrows. The side before keeps all its data (a window cut short before the change would date
        it from a few seconds of data). The kept split nearest the onset replaces it (and the start of the window
        after it).
        """
        from cart.identify import IdentifiabilityError, identify
        from cart.segments import find_segments

        if not (self.changes and self._refining) or end - self.changes[-1].t_detected > 0.5 * self.window_s:
            return
        last = self.changes[-1]
        log = self.window.log(self._before)
        try:
            res = identify(log)
            segs = find_segments(log, None, res)[0]
        except (IdentifiabilityError, np.linalg.LinAlgError, ValueError):
            return
        if len(segs) < 2:
            return
        k = min(range(1, len(segs)), key=lambda i: abs(segs[i]["t0"] - last.t_change))
        new = _change(segs[k - 1], segs[k], last.t_detected)
        self.changes[-1] = replace(new, after=last.after, after_std=last.after_std, refined=True)
        self.start = new.t_change + 1.0 / res.cutoff_hz


def _same_change(a: WindowChange, b: WindowChange) -> bool:
    """Return whether two checks found the same change: onsets within a second of each other or of the other's
    stretch, and the mass moving the same way."""
    near = min(abs(a.t_change - b.t_change), max(0.0, b.t_range[0] - a.t_change, a.t_change - b.t_range[1]))
    return near <= 1.0 and (a.after.m - a.before.m) * (b.after.m - b.before.m) > 0.0


def _change(before: dict, after: dict, t_detected: float) -> WindowChange:
    """Return the change between two segments of :func:`cart.segments.find_segments`."""
    lo, hi = after["t0_range"] or (after["t0"], after["t0"])
    return WindowChange(
        t_change=float(after["t0"]),
        t_range=(float(lo), float(hi)),
        t_detected=float(t_detected),
        before=before["params"],
        after=after["params"],
        after_std=dict(after["std"]),
    )
