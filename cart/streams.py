"""The pose and wrench of a log as the two sensor streams they are (multi-rate tables, dropouts, stuck sensors).

A real set-up records motion capture (the pose, 100-250 Hz) and an F/T sensor (the wrench,
500-1000 Hz) on their own clocks. Written into one table, the slower stream is either *held*
(a naive logger repeats the last pose on every F/T row, also through motion-capture dropouts)
or the faster one is averaged (a row per pose sample). :func:`split_streams` undoes the table:

- held pose rows (x, y, theta exactly equal to the previous row) are dropped when they make a
  fifth of the rows or more, or when short repeats (one or two rows) make ``MIN_HELD_SHARE`` of the
  rows or more about as often where the stream changes fast as where it changes slowly (two sensors at
  close rates, e.g. F/T at 120 Hz and motion capture at 100 Hz: a sixth of the rows; a finely quantised
  single-rate stream repeats only where it barely changes): a multi-rate table; the pose is then timed
  at the middle of the interval in which it first appeared (it arrived after the previous row). The
  wrench is held the same way when it is the slower stream;
- a pose interpolated linearly between motion-capture samples (at least a fifth of the rows on the
  straight line through their neighbours, in short runs) is a multi-rate table as well: the
  motion-capture samples are recovered as the corners between the straight pieces;
- in a single-rate table, a run of repeated poses during which the cart moved (the pose jumps at
  the run's end) is a dropout: the repeated rows are dropped, the interval becomes a gap;
- wrench rows repeated in every channel over at least ``STUCK_SECONDS`` (and 5 rows) are a stuck
  sensor: excluded (a gap), with a warning;
- isolated pose samples far from their neighbours (motion-capture glitches: beyond
  ``GLITCH_SCALE`` robust residual scales of a running median and several typical steps) are dropped.

The estimator (:mod:`cart.identify`) then samples each stream at its own instants.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cart._kernels_identify import median, median_columns
from cart.logs import CartLog

#: Share of rows repeating the previous pose above which the table is a multi-rate (held-pose) table.
HELD_SHARE = 0.2
#: Share of rows repeating the previous one in short runs above which a stream is held at a slower rate
#: (when the repeats do not cluster where the stream barely changes: :func:`held_rows`).
MIN_HELD_SHARE = 0.01
#: A wrench frozen in all channels this long (s) is a stuck sensor.
STUCK_SECONDS = 0.25
#: Gaps in a stream longer than this many of its median periods are dropouts.
DROPOUT_PERIODS = 2.5
#: The glitch test's pieces end at gaps longer than this many median periods (`_glitches_in_pieces`).
GLITCH_GAP_PERIODS = 5.0
#: A pose sample this many robust residual scales from its running median is a glitch.
GLITCH_SCALE = 12.0
#: A row whose slope changes by less than this share of the typical change lies on its neighbours' line.
LINE_TOLERANCE = 1e-2
#: The wrench and pose channels of a table, as named in warnings.
WRENCH_CHANNELS = ("fx", "fy", "tau")
POSE_CHANNELS = ("x", "y", "theta")
#: Longest median run of on-the-line rows of a pose interpolated between motion-capture samples.
MAX_PIECE_ROWS = 50


@dataclass(frozen=True)
class Stream:
    """One sensor stream: times (n,), values (n, 3) and the rows of the table they came from."""

    t: np.ndarray
    values: np.ndarray
    rows: np.ndarray

    @property
    def median_period(self) -> float:
        """Return the median interval between samples (s)."""
        return float(median(np.diff(self.t))) if len(self.t) > 1 else float("nan")

    @property
    def period(self) -> float:
        """Return the mean interval between samples outside dropouts (s): the stream's clock period."""
        if len(self.t) < 2:
            return float("nan")
        steps = np.diff(self.t)
        inside = steps[steps <= DROPOUT_PERIODS * median(steps)]
        return float(np.mean(inside))


@dataclass(frozen=True)
class Streams:
    """The log's pose and wrench streams and what was found while separating them.

    ``held_rows``: table rows that repeat the previous pose (dropped); ``dropouts``: (t0, t1) intervals
    without a pose sample; ``stuck``: (t0, t1) intervals of a frozen wrench (excluded), ``stuck_channels`` the
    channel frozen in each ("" when all are); ``frozen_pose``: (t0, t1, channel) where one pose channel repeats
    while the others change (those pose samples dropped); ``jumps``: the times where the pose jumps and stays
    (the pieces joined, :func:`join_jumps`), ``heading_jumps`` those of them where the heading alone jumps;
    ``saturated``: (channel, value, samples) of a wrench channel clipped at a fixed value (those samples
    excluded); ``glitches``: the times of dropped pose glitches;
    ``multi_rate``: the table holds the pose between motion-capture samples.
    """

    pose: Stream
    wrench: Stream
    held_rows: int
    dropouts: tuple[tuple[float, float], ...]
    stuck: tuple[tuple[float, float], ...]
    glitches: tuple[float, ...]
    multi_rate: bool
    interpolated: bool = False
    wrench_held_rows: int = 0
    wrench_missing_rows: int = 0
    stuck_channels: tuple[str, ...] = ()
    frozen_pose: tuple[tuple[float, float, str], ...] = ()
    jumps: tuple[float, ...] = ()
    heading_jumps: tuple[float, ...] = ()
    saturated: tuple[tuple[str, float, int], ...] = ()

    @property
    def pose_hz(self) -> float:
        """Return the pose stream's rate (1 / mean period outside dropouts)."""
        return 1.0 / self.pose.period

    @property
    def wrench_hz(self) -> float:
        """Return the wrench stream's rate (1 / mean period outside dropouts)."""
        return 1.0 / self.wrench.period

    def to_dict(self) -> dict[str, object]:
        """Return the JSON fields ``{pose_hz, wrench_hz, held_rows, wrench_held_rows, wrench_missing_rows,
        interpolated, dropouts, dropout_s, stuck_wrench_s, stuck_channels, frozen_pose_s, glitches, jumps,
        heading_jumps, saturated_channels, saturated_samples}``.

        ``held_rows``: the rows that are no pose sample of their own (held, or interpolated when
        ``interpolated``); ``wrench_held_rows`` the same for the wrench; ``wrench_missing_rows``: isolated
        all-zero wrench rows taken as missing samples."""
        return {
            "pose_hz": self.pose_hz,
            "wrench_hz": self.wrench_hz,
            "held_rows": self.held_rows,
            "wrench_held_rows": self.wrench_held_rows,
            "wrench_missing_rows": self.wrench_missing_rows,
            "interpolated": self.interpolated,
            "dropouts": len(self.dropouts),
            "dropout_s": float(sum(t1 - t0 for t0, t1 in self.dropouts)),
            "stuck_wrench_s": float(sum(t1 - t0 for t0, t1 in self.stuck)),
            "stuck_channels": sorted({name or "all" for name in self.stuck_channels}),
            "frozen_pose_s": float(sum(t1 - t0 for t0, t1, _ in self.frozen_pose)),
            "glitches": len(self.glitches),
            "jumps": len(self.jumps),
            "heading_jumps": len(self.heading_jumps),
            "saturated_channels": sorted({name for name, _, _ in self.saturated}),
            "saturated_samples": int(sum(n for _, _, n in self.saturated)),
        }

    def warnings(self) -> list[str]:
        """Return plain-language notes on what was found (held rows, stuck sensor, glitches)."""
        out = []
        if self.interpolated:
            out.append(
                f"multi-rate table: the pose is interpolated linearly between motion-capture samples on "
                f"{self.held_rows} rows; its samples recovered as the corners between straight pieces (pose at {self.pose_hz:.4g} Hz, "
                f"wrench at {self.wrench_hz:.4g} Hz, used as separate streams)"
            )
        elif self.multi_rate:
            out.append(
                f"multi-rate table: {self.held_rows} rows repeat the previous pose; pose at {self.pose_hz:.4g} Hz "
                f"and wrench at {self.wrench_hz:.4g} Hz used as separate streams"
            )
        if self.wrench_held_rows:
            out.append(
                f"multi-rate table: {self.wrench_held_rows} rows repeat the previous wrench; wrench at "
                f"{self.wrench_hz:.4g} Hz and pose at {self.pose_hz:.4g} Hz used as separate streams"
            )
        if self.wrench_missing_rows:
            out.append(
                f"{self.wrench_missing_rows} isolated rows have a wrench of exactly zero in every channel: "
                "taken as missing F/T samples"
            )
        for (t0, t1), name in zip(self.stuck, self.stuck_channels or ("",) * len(self.stuck)):
            what = f"{name} alone" if name else "the wrench"
            out.append(
                f"{what} is frozen from t = {t0:.3f} s to {t1:.3f} s ({t1 - t0:.3g} s): a stuck force "
                f"sensor{' axis' if name else ''}; that stretch is excluded"
            )
        for name, value, n in self.saturated:
            out.append(
                f"{name} reads its extreme value {value:.6g} exactly on {n} samples: clipped (a saturated force "
                "sensor axis); those samples are excluded"
            )
        for t0, t1, name in self.frozen_pose:
            out.append(
                f"the pose's {name} alone repeats one value from t = {t0:.3f} s to {t1:.3f} s ({t1 - t0:.3g} s) while "
                "the cart moves: a stuck motion-capture channel; those pose samples are dropped"
            )
        if self.heading_jumps:
            out.append(
                f"the heading alone jumps {len(self.heading_jumps)} time(s) (first at t = {self.heading_jumps[0]:.3f} s) "
                "while the positions carry on: a change of the heading's reference (a symmetric marker set read turned, "
                "a missed wrap); the later heading is shifted to continue the earlier one"
            )
        if len(self.jumps) > len(self.heading_jumps):
            frame = [x for x in self.jumps if x not in self.heading_jumps]
            out.append(
                f"the pose jumps and stays {len(frame)} time(s) (first at t = {frame[0]:.3f} s), far beyond "
                "the motion: a motion-capture re-registration or recordings written one after another; the pieces "
                "are joined by a rigid shift of the later pose (its world-frame force turned with it)"
            )
        if self.glitches:
            out.append(
                f"{len(self.glitches)} motion-capture glitch(es) dropped (first at t = {self.glitches[0]:.3f} s)"
            )
        return out


def box_average(t: np.ndarray, y: np.ndarray, tg: np.ndarray, dt: float) -> np.ndarray:
    """Return the mean of the piecewise-linear y(t) over [tg - dt/2, tg + dt/2] (anti-aliasing a faster stream)."""
    area = np.concatenate([np.zeros((1, y.shape[1])), np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t)[:, None], 0)])
    lo, hi = np.clip(tg - 0.5 * dt, t[0], t[-1]), np.clip(tg + 0.5 * dt, t[0], t[-1])
    width = np.maximum(hi - lo, 1e-300)
    out = np.column_stack([(np.interp(hi, t, area[:, i]) - np.interp(lo, t, area[:, i])) / width for i in range(3)])
    point = hi - lo <= 0.0
    if point.any():
        out[point] = np.column_stack([np.interp(tg[point], t, y[:, i]) for i in range(3)])
    return out


def _runs(same: np.ndarray) -> list[tuple[int, int]]:
    """Return [(first, last)] index ranges of rows i with same[i-1] true: runs repeating row first - 1."""
    d = np.diff(np.r_[0, same.astype(np.int8), 0])
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    return [(int(s) + 1, int(e)) for s, e in zip(starts, ends)]  # rows s+1 .. e repeat row s


def _repeats(v: np.ndarray) -> np.ndarray:
    """Return (n-1,) booleans: row i+1 equals row i in every column."""
    return np.all(v[1:] == v[:-1], axis=1)


def _slope_change(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Return (n,) the change of slope at rows 1..n-2 relative to its typical change (inf at the ends).

    Per column the change over the 90th percentile of changes (at least the rounding of float64
    values: a noise-free straight line is one run); the largest over x, y and theta.
    """
    dt = np.diff(t)
    slope = np.diff(q, axis=0) / dt[:, None]
    change = np.abs(np.diff(slope, axis=0))
    rounding = 1e-9 * (np.max(np.abs(q), axis=0) + 1.0) / float(median(dt))
    typical = np.maximum(np.percentile(change, 90, axis=0), rounding)
    out = np.full(len(t), np.inf)
    out[1:-1] = np.max(change / typical, axis=1)
    return out


def _interpolated_pose(log: CartLog) -> Stream | None:
    """Return the pose stream of a table whose pose was linearly interpolated to the rows' times, else None.

    Such a table (a logger interpolating motion capture to the F/T times) holds straight pieces between
    the motion-capture samples. Its slope changes are two-valued: at the rounding of the written values
    inside a piece (6 decimals are enough) and at the size of the motion-capture noise at the corners.
    The table is one when at least ``HELD_SHARE`` of the rows are on the line through their neighbours
    (change below ``LINE_TOLERANCE``), fewer than a tenth as many lie between that and ten times it (a
    smooth, noise-free pose has changes of every size instead), and the runs are no longer than
    ``MAX_PIECE_ROWS`` (a straight cruise at constant speed makes long runs). The motion-capture samples
    are recovered as the corners between consecutive pieces (:func:`_corners`).
    """
    t, q = log.t, log.q
    if len(t) < 10:
        return None
    r = _slope_change(t, q)
    line = r <= LINE_TOLERANCE
    between = int(np.sum((r > LINE_TOLERANCE) & (r <= 10.0 * LINE_TOLERANCE)))
    if line.sum() < HELD_SHARE * len(t) or between >= 0.1 * line.sum():
        return None
    runs = _runs(line[1:])
    if len(runs) < 2 or median([last - first + 1 for first, last in runs]) > MAX_PIECE_ROWS:
        return None  # one straight piece (a pose at rest) has no corners
    return _corners(t, q, runs)


def _corners(t: np.ndarray, q: np.ndarray, runs: list[tuple[int, int]]) -> Stream:
    """Return the corners of a piecewise-linear pose: where the lines of consecutive straight pieces meet.

    ``runs``: (first, last) rows lying inside each piece. Two pieces separated by exactly two rows (the
    last row of one, the first of the next) meet at one motion-capture sample; its time is where the two
    lines cross in the column whose slope changes most (relative to its typical change), its pose the
    first line at that time. ``rows`` holds the row before each corner.
    """
    a1 = np.array([last for _, last in runs[:-1]], dtype=int)
    b0 = np.array([first for first, _ in runs[1:]], dtype=int)
    ok = b0 - a1 == 3
    a1, b0 = a1[ok], b0[ok]
    ta, tb = t[a1 + 1], t[b0 - 1]
    s_a = (q[a1 + 1] - q[a1]) / (ta - t[a1])[:, None]
    s_b = (q[b0] - q[b0 - 1]) / (t[b0] - tb)[:, None]
    change = s_a - s_b
    col = np.argmax(np.abs(change) / (median_columns(np.abs(change)) + 1e-300), axis=1)
    k = np.arange(len(a1))
    gap = q[b0 - 1, col] - q[a1 + 1, col] - s_b[k, col] * (tb - ta)  # line B minus line A at ta
    tc = np.clip(ta + gap / change[k, col], ta, tb)
    qc = q[a1 + 1] + s_a * (tc - ta)[:, None]
    return Stream(tc, qc, a1 + 1)


def _activity(v: np.ndarray, half: int = 2) -> np.ndarray:
    """Return (n-1,) how fast the stream changes around each step: the largest change over 2 half + 1 rows
    per column, over the column's median such change."""
    n = len(v)
    lo = np.clip(np.arange(1, n) - half, 0, n - 1)
    hi = np.clip(np.arange(1, n) + half, 0, n - 1)
    change = np.abs(v[hi] - v[lo])
    return np.max(change / (median_columns(change) + 1e-300), axis=1)


def held_rows(v: np.ndarray) -> bool:
    """Return True when the stream ``v`` (n, k) is held between the samples of a slower sensor.

    The rows repeating the previous one in runs of typical length (at most twice the median run plus
    one: longer runs are dropouts or a standstill) make ``MIN_HELD_SHARE`` of the rows or more, and they
    are not concentrated where the stream changes slowly: among the steps where it changes faster than
    its median (over about four distinct samples), their share is at least half their share among the
    others. A held stream repeats at the sensors' rate ratio whatever the motion (F/T at 500 Hz and
    motion capture at 120 Hz: three rows in four; at 120 and 100 Hz: one in six); a quantised single-rate
    stream repeats only where it barely moves.
    """
    n = len(v)
    same = _repeats(v)
    runs = _runs(same)
    if n < 20 or not runs:
        return False
    longest = 2 * float(median([last - first + 1 for first, last in runs])) + 1
    short = np.zeros(n - 1, dtype=bool)
    for first, last in runs:
        if last - first + 1 <= longest:
            short[first - 1 : last] = True
    if short.sum() < max(MIN_HELD_SHARE * n, 10):
        return False
    fast = _activity(v, int(math.ceil(2.0 * n / max(n - int(same.sum()), 1)))) > 1.0
    if fast.sum() < 10 or (~fast).sum() < 10:
        return bool(short.sum() >= HELD_SHARE * n)
    return bool(np.mean(short[fast]) >= 0.5 * np.mean(short[~fast]))


def _pose_stream(log: CartLog) -> tuple[Stream, int, bool]:
    """Return (pose stream, held rows, multi-rate) with held rows and dropout repeats removed."""
    t, q = log.t, log.q
    n = len(t)
    same = _repeats(q)
    held = int(same.sum())
    keep = np.ones(n, dtype=bool)
    if n > 3 and held_rows(q):
        keep[1:] = ~same
        rows = np.flatnonzero(keep)
        tp = t[rows].copy()
        tp[1:] = 0.5 * (t[rows[1:] - 1] + t[rows[1:]])  # the sample arrived after the previous row
        return Stream(tp, q[rows], rows), held, True
    if held:
        step = np.hypot(*np.diff(q[:, :2], axis=0).T)
        typical = float(median(step[step > 0])) if np.any(step > 0) else 0.0
        for first, last in _runs(same):
            jump = float(np.hypot(*(q[min(last + 1, n - 1), :2] - q[first - 1, :2])))
            if last - first >= 2 and typical > 0 and jump > 2.5 * typical:
                keep[first : last + 1] = False
    rows = np.flatnonzero(keep)
    return Stream(t[rows], q[rows], rows), int((~keep).sum()), False


def _median_at(y: np.ndarray, idx: np.ndarray, half: int = 3, odd: tuple[bool, bool] = (False, False)) -> np.ndarray:
    """Return the median of y (n, k) over the 2 half + 1 samples around each index.

    The edges are reflected (y_k before the start); ``odd`` (start, end): reflected about the edge sample instead
    (2 y_0 - y_k), for a piece that ends at a dropout: the pose moved on across it, and an even reflection puts a
    moving cart's edge sample two steps from its median (the first sample after a dropout read as a glitch).
    """
    n = len(y)
    k = min(half, n - 1)
    head, tail = y[np.arange(k, 0, -1)], y[np.arange(n - 2, n - 2 - k, -1)]
    if odd[0]:
        head = 2.0 * y[0] - head
    if odd[1]:
        tail = 2.0 * y[-1] - tail
    pad = np.concatenate([head[:half], y, tail[:half]])
    pad = np.pad(pad, ((half - len(head[:half]), half - len(tail[:half])), (0, 0)), mode="edge")
    win = pad[idx[:, None] + np.arange(2 * half + 1)[None, :]]  # (m, window, k)
    return np.median(win, axis=1)


def _glitches(stream: Stream, odd: tuple[bool, bool] = (False, False)) -> np.ndarray:
    """Return booleans marking pose samples far beyond the noise and the motion from their running median
    (``odd``: the piece starts / ends at a dropout, :func:`_median_at`).

    The residual scale comes from at most ~20000 evenly spaced samples; the residual itself is computed
    only where the second difference stands out (every glitch does), so the cost is linear and small.
    """
    v = stream.values
    n = len(v)
    if n < 15:
        return np.zeros(n, dtype=bool)
    sample = np.arange(0, n, max(1, n // 20000))
    scale = 1.4826 * median_columns(np.abs(v[sample] - _median_at(v, sample, odd=odd))) + 1e-12
    d2 = np.abs(v[2:] - 2.0 * v[1:-1] + v[:-2])
    s2 = 1.4826 * median_columns(d2) + 1e-12
    hot = np.flatnonzero(np.any(d2 > 3.0 * s2, axis=1)) + 1
    cand = np.unique(np.clip(np.concatenate([hot - 1, hot, hot + 1]), 0, n - 1))
    bad = np.zeros(n, dtype=bool)
    if len(cand) == 0:
        return bad
    r = np.abs(v[cand] - _median_at(v, cand, odd=odd))
    step = median_columns(np.abs(np.diff(v, axis=0))) + 1e-12
    span = np.ptp(v, axis=0)
    bad[cand] = np.any((r > GLITCH_SCALE * scale) & (r > 5.0 * step) & (r > 1e-3 * span), axis=1)
    return bad


def _gap_steps(t: np.ndarray, periods: float = DROPOUT_PERIODS) -> np.ndarray:
    """Return the samples after which the time steps by more than ``periods`` median periods (a dropout)."""
    if len(t) < 3:
        return np.zeros(0, dtype=int)
    steps = np.diff(t)
    return np.flatnonzero(steps > periods * median(steps))


def _glitches_in_pieces(stream: Stream, cuts: np.ndarray) -> np.ndarray:
    """Return :func:`_glitches` of each piece between the jumps after samples ``cuts``, as one (n,) mask.

    A jump stays (:func:`_jump_steps`), so the samples on either side of it are no glitch: a running
    median across it lags the motion on one side (a pose moving against the jump's direction leaves its
    last samples several steps from the median), so each piece is tested on its own. So is each piece between
    dropouts longer than ``GLITCH_GAP_PERIODS`` (:func:`_gap_steps`), its edges there reflected oddly (the cart
    moved on across the gap: a lone sample inside an outside tester's 10 s dropout read as a glitch).
    """
    gaps = set(_gap_steps(stream.t, GLITCH_GAP_PERIODS).tolist())
    cuts = np.union1d(np.asarray(cuts, dtype=int), list(gaps)).astype(int)
    bounds = np.r_[0, cuts + 1, len(stream.t)]
    parts = [
        _glitches(Stream(stream.t[a:b], stream.values[a:b], stream.rows[a:b]), ((a - 1) in gaps, (b - 1) in gaps))
        for a, b in zip(bounds[:-1], bounds[1:])
    ]
    return np.concatenate(parts) if parts else np.zeros(0, dtype=bool)


def _stuck(t: np.ndarray, g: np.ndarray) -> list[tuple[int, int]]:
    """Return [(first, last)] row ranges where the wrench repeats the previous row in every channel long enough."""
    out = []
    for first, last in _runs(_repeats(g)):
        if last - first >= 4 and t[last] - t[first - 1] >= STUCK_SECONDS and (last - first) < 0.9 * len(t):
            out.append((first, last))
    return out


def _noisy(x: np.ndarray) -> bool:
    """Return True when the samples ``x`` carry measurement noise: their third differences are as large as their
    first (white or AR(1) noise: about 2.5 times; a smooth noise-free signal: a small fraction)."""
    d1 = np.abs(np.diff(x))
    d3 = np.abs(np.diff(x, 3))
    return bool(len(d3) > 10 and median(d3) > 0.5 * median(d1) > 0.0)


def frozen_channels(t: np.ndarray, v: np.ndarray, names: tuple[str, ...]) -> list[tuple[int, int, str]]:
    """Return [(first, last, name)]: table rows over which one channel of ``v`` repeats its value exactly, for
    ``STUCK_SECONDS`` and 5 samples or more, while the other channels change (one axis of a sensor stuck).

    Only samples that differ from the previous row somewhere count (rows held in every channel are a slower
    stream, or the whole sensor stuck: :func:`_stuck`). Only a channel that carries noise (:func:`_noisy`) and
    otherwise hardly ever repeats (under 5 % of its steps: not a quantised channel) can be stuck: a measured
    value never repeats exactly for a quarter of a second, a noise-free simulated one (a torque of exactly
    zero on a straight push) may.
    """
    d = np.flatnonzero(np.r_[True, ~_repeats(v)])
    if len(d) < 20:
        return []
    out = []
    for c, name in enumerate(names):
        same = v[d[1:], c] == v[d[:-1], c]
        long = [
            (f, l)
            for f, l in _runs(same)
            if l - f >= 4 and t[d[l]] - t[d[f - 1]] >= STUCK_SECONDS and l - f < 0.9 * len(d)
        ]
        inside = sum(l - f + 1 for f, l in long)
        if not long or same.sum() - inside > 0.05 * (len(same) - inside) or not _noisy(v[d[~np.r_[False, same]], c]):
            continue
        for f, l in long:
            out.append((int(d[f]), int(d[l + 1] - 1) if l + 1 < len(d) else len(t) - 1, name))
    return out


def saturated_channels(v: np.ndarray, names: tuple[str, ...]) -> list[tuple[str, float, np.ndarray]]:
    """Return [(name, value, rows)]: channels of ``v`` clipped at a fixed value (a saturated force sensor axis or
    its amplifier), with the rows that read it.

    A channel is clipped at its largest (or smallest) value when that exact value is read on 5 samples or more
    (counting only rows that differ from the previous row somewhere: a held, slower stream repeats every sample),
    most of them next to another (a force held beyond the limit reads it on consecutive samples; a recording
    repeated end to end reaches its peak once per copy) and, apart from it, the channel carries noise (:func:`_noisy`) and hardly ever repeats a value (under 5 % of
    its steps: not a quantised channel). A measured value never hits its own extreme exactly five times.
    """
    d = np.flatnonzero(np.r_[True, ~_repeats(v)])
    if len(d) < 50:
        return []
    out = []
    for c, name in enumerate(names):
        x = v[d, c]
        for value in (float(x.max()), float(x.min())):
            at = x == value
            rest = x[~at]
            in_runs = at & (np.r_[False, at[:-1]] | np.r_[at[1:], False])  # next to another clipped sample
            if at.sum() < 5 or 2 * in_runs.sum() < at.sum() or len(rest) < 20 or not _noisy(rest):
                continue
            if np.sum(rest[1:] == rest[:-1]) > 0.05 * len(rest):
                continue
            out.append((name, value, np.flatnonzero(v[:, c] == value)))
    return out


def _dropouts(stream: Stream) -> tuple[tuple[float, float], ...]:
    """Return the intervals between consecutive samples longer than ``DROPOUT_PERIODS`` median periods."""
    return tuple((float(stream.t[i]), float(stream.t[i + 1])) for i in _gap_steps(stream.t))


def _isolated_zeros(g: np.ndarray) -> np.ndarray:
    """Return (n,) booleans: rows whose wrench is exactly zero in every channel in runs of one or two rows
    between non-zero rows (a logger that writes 0 where no F/T sample arrived; a noisy sensor never reads
    exactly zero in all channels, and a noise-free one at rest stays at zero for long runs)."""
    zero = np.all(g == 0.0, axis=1)
    out = np.zeros(len(g), dtype=bool)
    d = np.diff(np.r_[0, zero.astype(np.int8), 0])
    for s0, s1 in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
        if s1 - s0 <= 2 and s0 > 0 and s1 < len(g):
            out[s0:s1] = True
    return out if out.sum() >= max(MIN_HELD_SHARE * len(g), 10) else np.zeros(len(g), dtype=bool)


def _wrench_stream(
    t: np.ndarray, g: np.ndarray
) -> tuple[Stream, list[tuple[float, float, str]], int, int, list[tuple[str, float, int]]]:
    """Return (wrench stream, stuck intervals (t0, t1, channel or "" for all), held rows, missing rows, saturated
    channels (name, value, samples)) of the table's wrench columns.

    Held rows (a slower F/T sensor, :func:`held_rows`) are dropped and each sample is timed at the middle
    of the interval in which it first appeared; isolated all-zero rows (:func:`_isolated_zeros`) are
    missing samples; a frozen wrench (:func:`_stuck`), one frozen channel (:func:`frozen_channels`) and the
    samples of a clipped channel (:func:`saturated_channels`) are excluded.
    """
    keep = np.ones(len(t), dtype=bool)
    held = 0
    if held_rows(g):  # the wrench is the slower, held stream
        same = _repeats(g)
        keep[1:] = ~same
        held = int(same.sum())
    missing = _isolated_zeros(g)
    keep &= ~missing
    saturated = saturated_channels(g, WRENCH_CHANNELS)
    clip = {(name, value) for name, value, _ in saturated}
    stuck = []
    for first, last, _name in [(f, l, "") for f, l in _stuck(t, g)] + frozen_channels(t, g, WRENCH_CHANNELS):
        keep[first : last + 1] = False
        if (_name, float(g[first, WRENCH_CHANNELS.index(_name)]) if _name else 0.0) not in clip:
            stuck.append((float(t[first - 1]), float(t[last]), _name))
    for _, _, rows in saturated:
        keep[rows] = False
    rows = np.flatnonzero(keep)
    tw = t[rows].copy()
    if held:
        prev = np.maximum(rows - 1, 0)
        tw[rows > 0] = 0.5 * (t[prev] + t[rows])[rows > 0]  # the sample arrived after the previous row
    sat = [(name, value, len(r)) for name, value, r in saturated]
    return Stream(tw, g[rows], rows), stuck, held, int(missing.sum()), sat


def _jump_steps(stream: Stream) -> np.ndarray:
    """Return the indices i where the pose jumps between samples i and i + 1 and stays (not a dropout).

    A jump is a step that departs from the one its neighbours' rates predict by ``GLITCH_SCALE`` robust
    scales of the second difference (noise and motion per step) over the log and around the step (a smooth
    start from rest is no jump) and by 5 typical steps (over the log and around the step), in a column; the interval is an ordinary one (a
    dropout's step is a gap's, :func:`_dropouts`). Isolated glitches are dropped before (:func:`_glitches`),
    so the pose stays at the new place after a jump. Only steps next to a second difference beyond
    ``GLITCH_SCALE`` scales (every jump makes two) are examined, so the cost is linear and small.
    """
    v, t = stream.values, stream.t
    n = len(v)
    if n < 15:
        return np.zeros(0, dtype=int)
    d2 = np.abs(np.diff(v, 2, axis=0))
    scale = 1.4826 * median_columns(d2[:: max(1, n // 20000)]) + 1e-12
    hot = np.flatnonzero(np.any(d2 > GLITCH_SCALE * scale, axis=1))
    cand = np.unique(np.clip(np.r_[hot, hot + 1], 0, n - 2))  # d2[j] spans steps j and j + 1
    if not len(cand):
        return np.zeros(0, dtype=int)
    dt = np.diff(t)
    step = np.diff(v, axis=0)
    rate = step / dt[:, None]
    near = np.clip(cand[:, None] + np.array([-3, -2, -1, 1, 2, 3])[None, :], 0, n - 2)
    dev = np.abs(step[cand] - np.median(rate[near], axis=1) * dt[cand, None])
    local = np.median(d2[np.clip(cand[:, None] + np.array([-4, -3, -2, 1, 2, 3])[None, :], 0, n - 3)], axis=1)
    typical = median_columns(np.abs(step[:: max(1, n // 20000)])) + 1e-12
    span = np.ptp(v, axis=0)
    typical = np.maximum(typical, np.median(np.abs(step[near]), axis=1))  # the log's and the local motion
    far = (dev > GLITCH_SCALE * scale) & (dev > GLITCH_SCALE * local) & (dev > 5.0 * typical) & (dev > 1e-3 * span)
    ordinary = dt[cand] <= DROPOUT_PERIODS * float(median(dt[:: max(1, n // 20000)]))
    return cand[_stays(stream, cand, np.median(rate[near], axis=1), far & ordinary[:, None])]


def _stays(stream: Stream, steps: np.ndarray, rate: np.ndarray, far: np.ndarray, half: int = 3) -> np.ndarray:
    """Return (m,) booleans: the step from sample i to i + 1 (``steps``, in order) is far (``far`` (m, 3)) and
    stays in a far column: a jump, not a glitch.

    A jump stays, a glitch comes back: in a far column, most (``half`` + 1 or more) of the 2 ``half`` + 1
    samples up to i (from the last jump found on) lie on the line through sample i at ``rate`` (m, 3), and
    most of the 2 ``half`` + 1 from i + 1 on on the line through sample i + 1, each within a quarter of the step's
    departure from that motion (up to ``half`` glitched samples in a row on either side leave a majority),
    and the medians of the two sets differ by the step after that motion, within half of it.
    A piece shorter than ``half`` + 1 samples between two jumps is taken for glitches.
    """
    v, t = stream.values, stream.t
    n = len(v)
    out = np.zeros(len(steps), dtype=bool)
    start = 0
    for k, i in enumerate(int(j) for j in steps):
        before, after = slice(max(i - 2 * half, start), i + 1), slice(i + 1, min(i + 2 + 2 * half, n))
        if not far[k].any() or i + 1 - before.start <= half:
            continue  # a step within ``half`` samples of the last jump: a glitch next to it
        dev = v[i + 1] - v[i] - rate[k] * (t[i + 1] - t[i])
        tol = 0.25 * np.abs(dev)
        near_b = np.abs(v[before] - v[i] - np.outer(t[before] - t[i], rate[k])) < tol
        near_a = np.abs(v[after] - v[i + 1] - np.outer(t[after] - t[i + 1], rate[k])) < tol
        most = (near_b.sum(axis=0) > half) & (near_a.sum(axis=0) >= min(half + 1, after.stop - after.start))
        moved = rate[k] * (median(t[after]) - median(t[before]))
        shift = median_columns(v[after]) - median_columns(v[before]) - moved
        out[k] = bool(np.any(far[k] & most & (np.abs(shift - dev) < 2.0 * tol)))
        start = i + 1 if out[k] else start
    return out


def _positions_continue(pose: Stream, i: int, half: int = 4) -> bool:
    """Return True when the heading alone jumps from sample i to i + 1: the positions step as
    the motion around the step predicts (within ``GLITCH_SCALE`` robust scales of the second difference around
    it) and the direction of travel does not turn with the heading (when the cart moves enough to tell).

    A heading that jumps while the path carries on (a symmetric marker set read turned by pi, a heading
    written modulo 2 pi with one wrap missed) is a change of the body's heading reference, not of the
    motion-capture frame: the positions and the world-frame wrench need no change. A frame turned about the
    cart's own position also leaves the positions in place, but turns the direction of travel with the heading.
    """
    p, t = pose.values, pose.t
    lo, hi = max(i - half, 0), min(i + 1 + half, len(p) - 1)
    if i - lo < 2 or hi - (i + 1) < 2:
        return False
    before = (p[i] - p[lo]) / max(t[i] - t[lo], 1e-12)
    after = (p[hi] - p[i + 1]) / max(t[hi] - t[i + 1], 1e-12)
    dev = p[i + 1] - p[i] - 0.5 * (before + after) * (t[i + 1] - t[i])
    d2 = np.abs(np.diff(np.r_[p[lo : i + 1], p[i + 1 : hi + 1] - (p[i + 1] - p[i])], 2, axis=0))
    scale = 1.4826 * median_columns(d2)[:2] + 1e-9
    step = median_columns(np.abs(np.diff(p[lo : hi + 1, :2], axis=0)))
    if not np.all(np.abs(dev[:2]) <= np.maximum(GLITCH_SCALE * scale, 2.0 * step)):
        return False
    moving = min(np.hypot(*before[:2]), np.hypot(*after[:2])) * (t[hi] - t[lo]) > 10.0 * float(np.max(scale))
    travel = math.remainder(math.atan2(after[1], after[0]) - math.atan2(before[1], before[0]), 2.0 * math.pi)
    turn = math.remainder(float(dev[2]), 2.0 * math.pi)  # a turn by 2 pi is no turn of the frame
    return not moving or abs(math.remainder(travel - turn, 2.0 * math.pi)) >= 0.5 * abs(turn)


def _piece_maps(pose: Stream, jumps: np.ndarray) -> list[tuple[float, np.ndarray, np.ndarray, bool]]:
    """Return, per piece after each jump, (heading offset, rotation, shift, heading alone) mapping its raw pose
    onto the continuation of the joined pose before it (:func:`join_jumps`); the rotation also turns its wrench.
    After a jump of the heading alone the positions keep the previous piece's rotation and shift."""
    q = pose.values.copy()
    bounds = np.r_[jumps + 1, len(q)]
    rot, shift = np.eye(2), np.zeros(2)
    maps = []
    for k, i in enumerate(jumps):
        lo = max(i - 3, 0)
        rate = (q[i] - q[lo]) / max(pose.t[i] - pose.t[lo], 1e-12) if i > lo else np.zeros(3)
        target = q[i] + rate * (pose.t[i + 1] - pose.t[i])  # q[: i + 1] already joined
        d = float(target[2] - pose.values[i + 1, 2])
        alone = _positions_continue(pose, int(i))
        if not alone:  # the frame moved: a rigid shift of the later pose
            c, s_ = math.cos(d), math.sin(d)
            rot = np.array([[c, -s_], [s_, c]])
            shift = target[:2] - rot @ pose.values[i + 1, :2]
        piece = slice(i + 1, bounds[k + 1])
        q[piece, :2] = pose.values[piece, :2] @ rot.T + shift
        q[piece, 2] = pose.values[piece, 2] + d
        maps.append((d, rot, shift, alone))
    return maps


def join_jumps(
    pose: Stream, wrench: Stream, jumps: np.ndarray | None = None
) -> tuple[Stream, Stream, tuple[float, ...], tuple[float, ...]]:
    """Return (pose, wrench, jump times, times of the heading-only jumps) with the pieces between pose jumps joined by rigid shifts.

    After a jump (:func:`_jump_steps`: a motion-capture re-registration, recordings written one after
    another) the later pose is moved rigidly (rotated by delta about the vertical, translated) to continue
    the earlier one at the rate of the samples before the jump; the world-frame force (fx, fy) after the
    jump turns by the same delta, so the body-frame velocities and the forward force the model sees are
    those of the recording (eq. 4 is invariant under a rigid change of the world frame): each piece is taken
    as recorded in its own frame (recordings written one after another). A re-registration that shifts the
    motion-capture frame is joined exactly; one that also turns it (the wrench's frame left as it was) leaves
    the later force turned by delta: the misfit, or the wrench-frame check (:mod:`cart.units`), says so. A jump
    of the heading alone (:func:`_positions_continue`: the positions carry on) only shifts the later heading.
    Too many jumps (over 1 % of the samples) is not a recording of one push: left as it is.
    """
    jumps = _jump_steps(pose) if jumps is None else jumps
    if not len(jumps) or len(jumps) > 0.01 * len(pose.t):
        return pose, wrench, (), ()
    q = pose.values.copy()
    g = wrench.values.copy()
    bounds = np.r_[jumps + 1, len(q)]
    maps = _piece_maps(pose, jumps)
    for k, (i, (d, rot, shift, _)) in enumerate(zip(jumps, maps)):
        piece = slice(i + 1, bounds[k + 1])
        q[piece, :2] = pose.values[piece, :2] @ rot.T + shift
        q[piece, 2] = pose.values[piece, 2] + d
        lo_w = int(np.searchsorted(wrench.t, 0.5 * (pose.t[i] + pose.t[i + 1]), side="right"))
        hi_w = len(g)
        if k + 1 < len(jumps):
            hi_w = int(np.searchsorted(wrench.t, 0.5 * (pose.t[jumps[k + 1]] + pose.t[jumps[k + 1] + 1]), side="right"))
        g[lo_w:hi_w, :2] = wrench.values[lo_w:hi_w, :2] @ rot.T
    times = tuple(float(0.5 * (pose.t[i] + pose.t[i + 1])) for i in jumps)
    heading = tuple(x for x, m in zip(times, maps) if m[3])
    return Stream(pose.t, q, pose.rows), Stream(wrench.t, g, wrench.rows), times, heading


def split_streams(log: CartLog) -> Streams:
    """Return the pose and wrench streams of ``log`` (held rows, dropouts, glitches, stuck wrench handled)."""
    pieces = _interpolated_pose(log) if not held_rows(log.q) else None
    if pieces is not None:
        pose, held, multi = pieces, len(log.t) - len(pieces.t), True
    else:
        pose, held, multi = _pose_stream(log)
    cuts = _jump_steps(pose)
    if len(cuts) > 0.01 * len(pose.t):
        cuts = cuts[:0]  # not a recording of one push (:func:`join_jumps`)
    bad = _glitches_in_pieces(pose, cuts)
    glitch_t = tuple(float(x) for x in pose.t[bad])
    frozen = []
    for first, last, name in frozen_channels(pose.t, pose.values, POSE_CHANNELS):
        bad[first : last + 1] = True
        frozen.append((float(pose.t[first - 1]), float(pose.t[last]), name))
    if bad.any():
        kept = np.cumsum(~bad) - 1  # the index of the last kept sample up to each one
        pose = Stream(pose.t[~bad], pose.values[~bad], pose.rows[~bad])
        cuts = np.unique(kept[cuts])
        cuts = cuts[(cuts >= 0) & (cuts < len(pose.t) - 1)]
    wrench, stuck, wrench_held, missing, saturated = _wrench_stream(log.t, log.gamma)
    pose, wrench, jumps, heading_jumps = join_jumps(pose, wrench, cuts)
    return Streams(
        pose=pose,
        wrench=wrench,
        held_rows=held,
        dropouts=_dropouts(pose),
        stuck=tuple((t0, t1) for t0, t1, _ in stuck),
        stuck_channels=tuple(name for _, _, name in stuck),
        frozen_pose=tuple(frozen),
        jumps=jumps,
        heading_jumps=heading_jumps,
        saturated=tuple(saturated),
        glitches=glitch_t,
        multi_rate=multi,
        interpolated=pieces is not None,
        wrench_held_rows=wrench_held,
        wrench_missing_rows=missing,
    )
