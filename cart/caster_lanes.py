"""Swivel angles of two modelled casters along a log, streamed: what the caster fits keep of them.

The swivelling-caster model (:class:`cart.effects.SwivelCasterModel`) steps the swivel angle of each
caster along the log for every axle position, trail and swing mode (:data:`cart.effects.SWING_MODES`:
924 lanes per sample). The fits use the *natural* lane everywhere and the other lanes only during the
swings, where the lanes disagree. :func:`caster_lanes` steps the log in chunks (the state carried from
one chunk to the next) and keeps only those: the natural lanes (single precision) and, per axle and
trail, the full lanes on the samples of its swings -- angles only: a swivel rate is a function of the angle
and the motion, recomputed when asked for. The working memory is one chunk's; what is kept grows with the
log by the natural lanes' angles plus the swings' share of the full ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: samples stepped per chunk (the working arrays are a chunk's)
CHUNK = 2048
#: a sample belongs to a swing when some lane's angle differs from the natural one by more than this
#: (|sin(half the difference)|)
SWING_SPLIT = 0.02


@dataclass(frozen=True)
class CasterLanes:
    """Swivel angles of :func:`caster_lanes` for a grid of axle positions x trails; their rates on demand.

    ``alpha0``: the natural lane (N, axles, trails, 2 casters), single precision;
    ``swings[(i, j)]``: the sample ranges [i0, i1) of axle i, trail j where the lanes disagree;
    ``swing_alpha[(i, j)]``: every lane on those samples, one array (L, 2 casters, modes) per swing, in the
    order of ``swings``. The swivel rates are not kept: a rate is a function of the angle and the motion
    (the no-side-slip kinematics), recomputed from the kept angles (:meth:`natural_rate`, :meth:`swing_rates`)
    as the pass computed it. ``v``, ``om``: the forward speed and yaw rate of the pass (the caller's arrays).
    """

    alpha0: np.ndarray
    swings: dict[tuple[int, int], list[tuple[int, int]]]
    swing_alpha: dict[tuple[int, int], list[np.ndarray]]
    v: np.ndarray
    om: np.ndarray
    axles: tuple[float, ...]
    trails: tuple[float, ...]
    half_track: float

    def natural_rate(self, i: int, j: int, lo: int = 0, hi: int | None = None) -> np.ndarray:
        """Return the swivel rates (N, 2 casters) of the natural lane of axle i, trail j (single precision).

        ``lo``, ``hi``: those of samples [lo, hi) only (the same values).
        """
        ys = np.array([self.half_track, -self.half_track])
        v, om = self.v[lo:hi, None], self.om[lo:hi, None]
        return _rates(self.alpha0[lo:hi, i, j], v, om, self.axles[i], ys, self.trails[j])

    def swing_rates(self, i: int, j: int, k: int) -> np.ndarray:
        """Return the swivel rates (L, 2 casters, modes) of every lane on swing k of axle i, trail j."""
        i0, i1 = self.swings[(i, j)][k]
        ys = np.array([self.half_track, -self.half_track])[None, :, None]
        v, om = self.v[i0:i1, None, None], self.om[i0:i1, None, None]
        return _rates(self.swing_alpha[(i, j)][k], v, om, self.axles[i], ys, self.trails[j])

    @property
    def rate0(self) -> np.ndarray:
        """Return the natural lanes' rates (N, axles, trails, 2), recomputed."""
        out = np.empty_like(self.alpha0)
        for i in range(len(self.axles)):
            for j in range(len(self.trails)):
                out[:, i, j] = self.natural_rate(i, j)
        return out

    @property
    def swing_rate(self) -> dict[tuple[int, int], list[np.ndarray]]:
        """Return the rates of every lane on the swings, as ``swing_alpha`` (recomputed)."""
        return {key: [self.swing_rates(*key, k) for k in range(len(r))] for key, r in self.swings.items()}


def _rates(alpha: np.ndarray, v: np.ndarray, om: np.ndarray, x, y, trail) -> np.ndarray:
    """Return alpha' = (-qx sin alpha + qy cos alpha) / e - omega, (qx, qy) = (v - omega y, omega x), single precision.

    The rate of a caster at (x, y) with trail e rolling without sliding sideways, at the angle as kept (single
    precision); the arguments broadcast.
    """
    a = np.asarray(alpha).astype(float)
    qx = v - om * y
    qy = om * x
    return ((-qx * np.sin(a) + qy * np.cos(a)) / trail - om).astype(np.float32)


def _ranges(on: np.ndarray) -> list[tuple[int, int]]:
    """Return the [i0, i1) ranges where the boolean ``on`` is True."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], on.astype(np.int8), [0]])))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]


class _Stepper:
    """The projective swivel state (p, q), tan(b / 2) = p / q, b = alpha - psi, carried across chunks."""

    def __init__(self, psi0: np.ndarray, shape: tuple[int, ...], side: np.ndarray, lim: np.ndarray) -> None:
        b0 = -psi0  # alpha = 0 at the start: the casters start trailing
        self.p = np.broadcast_to(np.sin(0.5 * b0), shape).copy()
        self.q = np.broadcast_to(np.cos(0.5 * b0), shape).copy()
        self.tl = np.tan(0.5 * lim)  # |b| > lim  <=>  |p| > tan(lim / 2) |q|
        self.side = side
        self.forced = side != 0.0
        self.count = 0

    def run(self, decay: np.ndarray, cs: np.ndarray, sn: np.ndarray, last: bool) -> tuple[np.ndarray, np.ndarray]:
        """Return (p, q) at the chunk's samples (k, ...): clamp, decay, then rotate towards the next sample.

        ``cs`` / ``sn``: cos / sin of half the reference change towards each next sample (k - 1 of them
        when ``last``, else k: the chunk's last step leads into the next chunk).
        """
        k = len(decay)
        buf_p = np.empty((k,) + self.p.shape)
        buf_q = np.empty_like(buf_p)
        p, q = self.p, self.q
        for i in range(k):
            far = np.abs(p) > self.tl * np.abs(q)
            if far.any():
                sgn = np.where(self.forced, self.side, np.sign(p * q))
                p = np.where(far, sgn * self.tl, p)
                q = np.where(far, 1.0, q)
            p = p * decay[i]
            buf_p[i], buf_q[i] = p, q
            if i < len(cs):
                p, q = p * cs[i] + q * sn[i], q * cs[i] - p * sn[i]
                if self.count % 32 == 0:  # keep the pair of order one
                    scale = np.abs(p) + np.abs(q)
                    p, q = p / scale, q / scale
            self.count += 1
        self.p, self.q = p, q
        return buf_p, buf_q


@dataclass(frozen=True)
class _Geometry:
    """Caster positions, trails and swing modes broadcast over (axles, trails, 2 casters, modes)."""

    xs: np.ndarray
    ys: np.ndarray
    es: np.ndarray
    side: np.ndarray
    lim: np.ndarray


def _chunk_angles(geo: _Geometry, st: _Stepper, c: slice, last: bool, kin: tuple[np.ndarray, ...]) -> np.ndarray:
    """Return the swivel angles (k, axles, trails, 2, modes) of the samples ``c`` (stepping ``st``), single precision."""
    vm, omm, dt = kin
    stop = c.stop if last else c.stop + 1  # the reference direction of the next sample, for the last rotation
    px = vm[c.start : stop, None, None, None, None] - omm[c.start : stop, None, None, None, None] * geo.ys[None]
    py = omm[c.start : stop, None, None, None, None] * geo.xs[None]
    psi = np.arctan2(py, px)  # (k (+1), nx, 1, 2, 1)
    k = c.stop - c.start
    decay = np.exp(-(np.hypot(px[:k], py[:k]) * dt[c, None, None, None, None]) / geo.es[None])
    yaw = omm[c.start : stop] * dt[c.start : stop]
    half = 0.5 * (psi[:-1] - yaw[: len(psi) - 1, None, None, None, None] - psi[1:])
    bp, bq = st.run(decay, np.cos(half), np.sin(half), last)
    return (2.0 * np.arctan2(bp, bq) + psi[:k] - yaw[:k, None, None, None, None]).astype(np.float32)


def caster_lanes(
    t: np.ndarray,
    v: np.ndarray,
    om: np.ndarray,
    axles: tuple[float, ...],
    trails: tuple[float, ...],
    modes: tuple[tuple[int, float], ...],
    half_track: float,
) -> CasterLanes:
    """Return the casters' swivel angles and rates (:class:`CasterLanes`), stepped in chunks of CHUNK samples.

    Casters at (x, +-half_track) in {b} with trail e roll along alpha without sliding sideways:
    alpha' = -(R / e) sin(alpha - psi) - omega, (R cos psi, R sin psi) = (v - omega y, omega x) the swivel
    axis's velocity. Per sample the angle b = alpha - psi decays exactly as tan(b / 2) -> tan(b / 2)
    exp(-R dt / e) (any sampling rate is stable) and is clamped to at least the mode's misalignment from
    leading (side 0: the side it is on, +-1: forced). ``v``: forward speed, ``om``: the yaw rate driving
    the kinematics (speeds at the interval midpoints step the angle, the sample's give its rate).
    """
    nx, nt, nm = len(axles), len(trails), len(modes)
    geo = _Geometry(
        xs=np.asarray(axles, float)[:, None, None, None],
        ys=np.array([half_track, -half_track])[None, None, :, None],
        es=np.asarray(trails, float)[None, :, None, None],
        side=np.array([m[0] for m in modes], float)[None, None, None, :],
        lim=np.pi - np.array([m[1] for m in modes])[None, None, None, :],
    )
    vm = np.concatenate([[v[0]], 0.5 * (v[1:] + v[:-1])])
    omm = np.concatenate([[om[0]], 0.5 * (om[1:] + om[:-1])])
    dt = np.concatenate([[0.0], np.diff(t)])
    psi0 = np.arctan2(omm[0] * geo.xs, vm[0] - omm[0] * geo.ys)
    side = np.broadcast_to(np.where(geo.side != 0, geo.side, 0.0), (nx, nt, 2, nm))
    st = _Stepper(psi0, (nx, nt, 2, nm), side, geo.lim)
    n = len(t)
    alpha0 = np.empty((n, nx, nt, 2), np.float32)
    on = np.zeros((n, nx, nt), bool)
    kept: dict[tuple[int, int], list[np.ndarray]] = {}
    for c0 in range(0, n, CHUNK):
        c = slice(c0, min(c0 + CHUNK, n))
        alpha = _chunk_angles(geo, st, c, c.stop == n, (vm, omm, dt))
        alpha0[c] = alpha[..., 0]
        on[c] = np.max(np.abs(np.sin(0.5 * (alpha - alpha[..., :1]))), axis=(3, 4)) > SWING_SPLIT
        for i, j in zip(*np.nonzero(np.any(on[c], axis=0))):
            kept.setdefault((int(i), int(j)), []).append(alpha[np.flatnonzero(on[c, i, j]), i, j])
    swings, s_alpha = _assemble(on, kept, alpha0.shape[-1:])
    return CasterLanes(alpha0, swings, s_alpha, v, om, tuple(axles), tuple(trails), float(half_track))


def _assemble(
    on: np.ndarray, kept: dict[tuple[int, int], list[np.ndarray]], tail: tuple[int, ...]
) -> tuple[dict[tuple[int, int], list[tuple[int, int]]], dict[tuple[int, int], list[np.ndarray]]]:
    """Return the swing ranges and every lane on each swing per (axle, trail), from the swing samples kept."""
    swings, s_alpha = {}, {}
    for i in range(on.shape[1]):
        for j in range(on.shape[2]):
            ranges = _ranges(on[:, i, j])
            swings[(i, j)] = ranges
            parts = kept.get((i, j), [])
            a = np.concatenate(parts) if parts else np.empty((0,) + tail)
            cuts = np.cumsum([i1 - i0 for i0, i1 in ranges])[:-1]
            s_alpha[(i, j)] = np.split(a, cuts) if ranges else []
    return swings, s_alpha
