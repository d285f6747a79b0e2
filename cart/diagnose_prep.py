"""A log made ready for diagnosis: its two sensor streams on one time base, time origin 0, bounded size.

``prepare_log(log) -> Prepared``:

1. **Streams.** :func:`cart.streams.split_streams` separates the pose (motion capture) and the wrench
   (F/T) the table interleaves: a multi-rate table that holds the pose between motion-capture
   samples, dropout repeats, glitches, a stuck force sensor. The diagnosis runs on the pose
   samples, with the wrench averaged over the interval around each (half-way to the neighbours;
   interpolated where that interval holds no wrench sample). A held pose read as motion stops and
   jumps at the motion-capture rate: the nominal fit of such a table is not a cart. The wrench samples
   the streams exclude (a clipped axis, a stuck sensor) leave holes in the wrench stream whose fill is no
   measurement (across a clipped peak it reads the clip level): ``wrench_holes`` lists them, and the
   diagnosis leaves the windows that reach them out of its fits, as ``estimate`` leaves them out.
2. **Working rate.** A log of more than ``MAX_SAMPLES`` samples is averaged over blocks of
   consecutive samples (never below ``MIN_RATE`` Hz), so the per-sample work (smoothing, caster
   kinematics, effect columns) is bounded; what grows with the log's duration is the number of
   0.3 s fit windows and 1 s replays (linear).
3. **Time origin.** Times start at 0 inside the diagnosis (``time_offset`` is added back to every
   reported time): absolute clock times (e.g. Unix seconds) change nothing.

Every change is reported in ``notes`` (the report's ``warnings``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cart.logs import CartLog

if TYPE_CHECKING:
    from cart.streams import Streams

#: Above this many samples the diagnosis averages blocks of consecutive samples.
MAX_SAMPLES = 60000
#: The block averaging never brings a log below this rate (Hz).
MIN_RATE = 50.0
#: Fewer distinct pose samples than this: the table is left as it is (and refused later if it does not move).
MIN_POSES = 20


@dataclass(frozen=True)
class Prepared:
    """A log ready for diagnosis: ``log`` (time origin 0), ``time_offset`` (s), ``block`` size, ``notes``,
    ``wrench_holes``: (t0, t1) intervals (in ``log``'s time) where the wrench was filled, not measured."""

    log: CartLog
    time_offset: float
    block: int
    notes: tuple[str, ...]
    wrench_holes: tuple[tuple[float, float], ...] = ()


def _split(log: CartLog):
    """Return :func:`cart.streams.split_streams` of ``log`` (None when that module is not available)."""
    try:
        from cart.streams import split_streams
    except ImportError:  # pragma: no cover - the streams module ships with the package
        return None
    return split_streams(log)


def wrench_at_pose_times(tp: np.ndarray, tw: np.ndarray, gw: np.ndarray) -> np.ndarray:
    """Return the wrench (len(tp), 3) at the pose times: the mean over [mid(k-1, k), mid(k, k+1)), else interpolated.

    ``tw``, ``gw``: the wrench stream's times and values (increasing times).
    """
    tp = np.asarray(tp, float)
    mids = 0.5 * (tp[1:] + tp[:-1])
    lo = np.searchsorted(tw, np.concatenate([[-np.inf], mids]), side="left")
    hi = np.searchsorted(tw, np.concatenate([mids, [np.inf]]), side="left")
    cum = np.vstack([np.zeros((1, gw.shape[1])), np.cumsum(gw, axis=0)])
    cnt = hi - lo
    out = np.column_stack([np.interp(tp, tw, gw[:, k]) for k in range(gw.shape[1])])
    some = cnt > 0
    out[some] = (cum[hi[some]] - cum[lo[some]]) / cnt[some, None]
    return out


def wrench_holes(log: CartLog, st: Streams) -> tuple[tuple[float, float], ...]:
    """Return the (t0, t1) intervals of the wrench stream that hold samples the streams excluded, in ``log``'s time.

    ``st``: the :class:`cart.streams.Streams` of ``log``. Excluded are the rows of a clipped channel (that
    channel at its clip value, ``st.saturated``) and a stuck sensor's (``st.stuck``); each hole runs from the
    last kept wrench sample before them to the first after (the stretch the merged wrench fills).
    """
    from cart.streams import WRENCH_CHANNELS

    t, g, tw = np.asarray(log.t, float), np.asarray(log.gamma, float), st.wrench.t
    out = np.zeros(len(t), dtype=bool)
    for name, value, _ in st.saturated:
        out |= g[:, WRENCH_CHANNELS.index(name)] == value
    for t0, t1 in st.stuck:
        out |= (t > t0) & (t <= t1)
    te = t[out]
    if len(te) == 0 or len(tw) == 0:
        return ()
    i = np.searchsorted(tw, te)
    lo = np.where(i > 0, tw[np.maximum(i - 1, 0)], te)
    hi = np.where(i < len(tw), tw[np.minimum(i, len(tw) - 1)], te)
    return tuple((float(a), float(b)) for a, b in np.unique(np.column_stack([lo, hi]), axis=0))


def _merge_streams(log: CartLog, notes: list[str], holes: list[tuple[float, float]]) -> CartLog:
    """Return ``log`` on its pose stream's samples with the wrench stream averaged onto them (unchanged if clean);
    append the wrench's holes (:func:`wrench_holes`) to ``holes``."""
    st = _split(log)
    if st is None:
        return log
    from cart.units import check_declared_units, check_units

    check_declared_units(log.metadata, log.source)
    check_units(st, log.source)  # time in ms, positions in mm, heading in degrees: refused as `estimate` does
    clean = (
        not st.multi_rate
        and len(st.pose.t) == len(log.t)
        and len(st.wrench.t) == len(log.t)
        and not st.stuck
        and not st.glitches
        and not st.jumps
    )
    if clean or len(st.pose.t) < MIN_POSES:  # a cart that never moves repeats one pose: nothing to separate
        return log
    notes.extend(st.warnings())
    holes.extend(wrench_holes(log, st))
    if not st.multi_rate and len(st.pose.t) < len(log.t) - len(st.glitches):
        notes.append(
            f"{len(log.t) - len(st.pose.t) - len(st.glitches)} rows repeat a pose while the cart moved "
            "(motion-capture dropouts): left out of the pose"
        )
    g = wrench_at_pose_times(st.pose.t, st.wrench.t, st.wrench.values)
    return CartLog(t=st.pose.t, q=st.pose.values, gamma=g, qd=None, metadata=dict(log.metadata), source=log.source)


def _block_average(log: CartLog, notes: list[str]) -> tuple[CartLog, int]:
    """Return ``log`` averaged over blocks of consecutive samples when it has more than MAX_SAMPLES, and the block."""
    n = len(log.t)
    if n <= MAX_SAMPLES:
        return log, 1
    rate = (n - 1) / max(float(log.t[-1] - log.t[0]), 1e-12)
    block = min(math.ceil(n / MAX_SAMPLES), max(int(rate / MIN_RATE + 0.01), 1))
    if block <= 1:
        return log, 1
    q = np.array(log.q, float)
    q[:, 2] = np.unwrap(q[:, 2])
    starts = np.arange(0, n, block)
    cnt = np.diff(np.r_[starts, n])[:, None]

    def avg(y: np.ndarray) -> np.ndarray:
        y2 = np.asarray(y, float).reshape(n, -1)
        return np.add.reduceat(y2, starts, axis=0) / cnt

    notes.append(
        f"{n} samples at {rate:.4g} Hz: averaged over blocks of {block} consecutive samples "
        f"({rate / block:.4g} Hz) for the diagnosis"
    )
    out = CartLog(
        t=avg(log.t)[:, 0], q=avg(q), gamma=avg(log.gamma), qd=None, metadata=dict(log.metadata), source=log.source
    )
    return out, block


def prepare_log(log: CartLog) -> Prepared:
    """Return ``log`` ready for diagnosis: streams merged on the pose samples, bounded size, time origin 0."""
    notes: list[str] = []
    holes: list[tuple[float, float]] = []
    merged = _merge_streams(log, notes, holes)
    small, block = _block_average(merged, notes)
    t0 = float(small.t[0])
    shifted = CartLog(
        t=np.asarray(small.t, float) - t0,
        q=small.q,
        gamma=small.gamma,
        qd=small.qd,
        metadata=dict(small.metadata),
        source=small.source,
    )
    return Prepared(
        log=shifted,
        time_offset=t0,
        block=block,
        notes=tuple(notes),
        wrench_holes=tuple((a - t0, b - t0) for a, b in holes),
    )
