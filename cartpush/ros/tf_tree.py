"""A TF buffer for recorded data: static and dynamic transforms, time-interpolated lookups along chains.

The frames form a forest (ROS TF): each transform message gives the pose of a
*child* frame in its *parent* frame, ``T_parent_child`` (a point ``x_child``
maps to ``R @ x_child + p`` in the parent). `TransformBuffer.lookup` returns
``T_target_source`` at an array of times by walking the tree from ``source``
to ``target`` through any number of frames, interpolating every dynamic link
at each time (translation linearly, rotation by slerp) and composing. Static
links (``/tf_static``) hold at every time.

Frame ids are compared without leading slashes (ROS 1 writes ``/base_link``,
ROS 2 ``base_link``): :func:`normalize_frame`. Like tf2, a dynamic link is not
extrapolated: a time outside the span of its samples (beyond ``tolerance``) is
reported as invalid in the lookup's ``valid`` mask rather than guessed.

Times are plain floats (seconds, any zero the caller picks: keep them small,
e.g. relative to the start of a recording, so that float64 resolves
nanoseconds). Quaternions are ``(x, y, z, w)`` as in ROS messages.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from collections.abc import Iterable, Sequence

import numpy as np
import numpy.typing as npt

from cartpush.ros.errors import TransformLookupError

#: Quaternions shorter than this are not rotations: samples carrying them are skipped (counted as invalid).
MIN_QUATERNION_NORM = 1e-6


def normalize_frame(frame: str) -> str:
    """Return the frame id without surrounding blanks and leading slashes (``/odom`` and ``odom`` are one frame)."""
    return str(frame).strip().lstrip("/")


def quaternion_to_matrix(q: np.ndarray) -> np.ndarray:
    """Return rotation matrices (..., 3, 3) of quaternions (..., 4) in ROS order (x, y, z, w), normalized first."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - z * w)
    R[..., 0, 2] = 2 * (x * z + y * w)
    R[..., 1, 0] = 2 * (x * y + z * w)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - x * w)
    R[..., 2, 0] = 2 * (x * z - y * w)
    R[..., 2, 1] = 2 * (y * z + x * w)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def slerp(q0: np.ndarray, q1: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Return unit quaternions (N, 4) on the shortest great arc from q0 (N, 4) to q1 (N, 4) at fractions u (N,)."""
    q0 = np.asarray(q0, dtype=float)
    q1 = np.asarray(q1, dtype=float)
    u = np.asarray(u, dtype=float)[:, None]
    q0 = q0 / np.linalg.norm(q0, axis=1, keepdims=True)
    q1 = q1 / np.linalg.norm(q1, axis=1, keepdims=True)
    dot = np.sum(q0 * q1, axis=1, keepdims=True)
    q1 = np.where(dot < 0.0, -q1, q1)  # q and -q are one rotation: take the short way
    dot = np.abs(dot)
    angle = np.arccos(np.clip(dot, -1.0, 1.0))
    sin = np.sin(angle)
    small = sin < 1e-9
    safe = np.where(small, 1.0, sin)
    w0 = np.where(small, 1.0 - u, np.sin((1.0 - u) * angle) / safe)
    w1 = np.where(small, u, np.sin(u * angle) / safe)
    out = w0 * q0 + w1 * q1
    return out / np.linalg.norm(out, axis=1, keepdims=True)


@dataclass(frozen=True)
class EdgeInfo:
    """One parent -> child link of the TF forest: static or dynamic, how many samples, over which times."""

    parent: str
    child: str
    static: bool
    count: int
    first: float
    last: float
    duplicates: int
    invalid: int

    def to_dict(self) -> dict:
        """Return the link as a JSON-ready dict."""
        return {
            "parent": self.parent,
            "child": self.child,
            "static": self.static,
            "count": self.count,
            "first": self.first,
            "last": self.last,
            "duplicate_stamps": self.duplicates,
            "invalid": self.invalid,
        }


class _Edge:
    """The samples of one link ``T_parent_child`` (dynamic: sorted by stamp on demand)."""

    def __init__(self, parent: str, child: str) -> None:
        self.parent = parent
        self.child = child
        self._static_value: tuple[np.ndarray, np.ndarray] | None = None  # (p, q) of a static link
        self._stamps: list[float] = []
        self._p: list[Sequence[float]] = []
        self._q: list[Sequence[float]] = []
        self._arrays: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.duplicates = 0
        self.invalid = 0

    @property
    def static(self) -> bool:
        """True when the link is static (its last update was `set_static`, not `append`)."""
        return self._static_value is not None

    def set_static(self, p: npt.ArrayLike, q: npt.ArrayLike) -> None:
        self._static_value = (np.asarray(p, dtype=float), np.asarray(q, dtype=float))

    def append(self, stamps: npt.ArrayLike, p: npt.ArrayLike, q: npt.ArrayLike) -> None:
        self._static_value = None
        self._stamps.extend(np.asarray(stamps, dtype=float).tolist())
        self._p.extend(np.asarray(p, dtype=float).reshape(-1, 3).tolist())
        self._q.extend(np.asarray(q, dtype=float).reshape(-1, 4).tolist())
        self._arrays = None

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (stamps (n,), p (n, 3), q (n, 4)) sorted by stamp, one sample per stamp (the first received)."""
        if self._arrays is None:
            t = np.asarray(self._stamps, dtype=float)
            p = np.asarray(self._p, dtype=float).reshape(-1, 3)
            q = np.asarray(self._q, dtype=float).reshape(-1, 4)
            order = np.argsort(t, kind="stable")
            t, p, q = t[order], p[order], q[order]
            keep = np.ones(len(t), dtype=bool)
            keep[1:] = np.diff(t) > 0.0
            self.duplicates = int(np.count_nonzero(~keep))
            self._arrays = (t[keep], p[keep], q[keep])
        return self._arrays

    def count(self) -> int:
        return 1 if self.static else len(self.arrays()[0])

    def span(self) -> tuple[float, float]:
        if self.static:
            return (-np.inf, np.inf)
        t = self.arrays()[0]
        return (float(t[0]), float(t[-1])) if len(t) else (np.nan, np.nan)

    def at(self, times: np.ndarray, tolerance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (R (N, 3, 3), p (N, 3), valid (N,)) of T_parent_child at ``times``."""
        n = len(times)
        static = self._static_value
        if static is not None:
            p, q = static
            return (
                np.broadcast_to(quaternion_to_matrix(q), (n, 3, 3)).copy(),
                np.broadcast_to(p, (n, 3)).copy(),
                np.ones(n, dtype=bool),
            )
        t, p, q = self.arrays()
        if len(t) == 0:
            return np.broadcast_to(np.eye(3), (n, 3, 3)).copy(), np.zeros((n, 3)), np.zeros(n, dtype=bool)
        valid = (times >= t[0] - tolerance) & (times <= t[-1] + tolerance)
        if len(t) == 1:
            return (
                np.broadcast_to(quaternion_to_matrix(q[0]), (n, 3, 3)).copy(),
                np.broadcast_to(p[0], (n, 3)).copy(),
                valid,
            )
        i = np.clip(np.searchsorted(t, times, side="right") - 1, 0, len(t) - 2)
        u = np.clip((times - t[i]) / (t[i + 1] - t[i]), 0.0, 1.0)
        pos = p[i] + u[:, None] * (p[i + 1] - p[i])
        rot = quaternion_to_matrix(slerp(q[i], q[i + 1], u))
        return rot, pos, valid


def _clean(p: npt.ArrayLike, q: npt.ArrayLike) -> np.ndarray:
    """Return the mask of samples with finite values and a quaternion that is a rotation."""
    p = np.asarray(p, dtype=float).reshape(-1, 3)
    q = np.asarray(q, dtype=float).reshape(-1, 4)
    ok = np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(q), axis=1)
    norms = np.linalg.norm(np.where(np.isfinite(q), q, 0.0), axis=1)
    return ok & (norms > MIN_QUATERNION_NORM)


class TransformBuffer:
    """Static and dynamic TF links; ``lookup(target, source, times)`` interpolates along the chain between them.

    Example::

        buf = TransformBuffer()
        buf.add_static("arm_link", "ft_sensor", [0, 0, 0.1], [0, 0, 0, 1])
        buf.add_many("base", "arm_link", stamps, translations, quaternions)
        R, p, valid = buf.lookup("base", "ft_sensor", times)   # T_base_ft_sensor at each time
    """

    def __init__(self) -> None:
        self._edges: dict[tuple[str, str], _Edge] = {}
        self._adjacency: dict[str, dict[str, tuple[str, str]]] = {}

    # -- filling -------------------------------------------------------------------------------
    def _edge(self, parent: str, child: str) -> _Edge:
        parent, child = normalize_frame(parent), normalize_frame(child)
        if parent == child:
            raise TransformLookupError(
                f"a transform from frame '{parent}' to itself is not a TF link", source=child, target=parent
            )
        key = (parent, child)
        if key not in self._edges:
            self._edges[key] = _Edge(parent, child)
            self._adjacency.setdefault(parent, {})[child] = key
            self._adjacency.setdefault(child, {})[parent] = key
        return self._edges[key]

    def add_static(self, parent: str, child: str, translation: npt.ArrayLike, rotation: npt.ArrayLike) -> None:
        """Record a static link T_parent_child (translation (3,), quaternion (x, y, z, w)); the latest one holds."""
        edge = self._edge(parent, child)
        if not _clean(translation, rotation)[0]:
            edge.invalid += 1
            return
        edge.set_static(translation, rotation)

    def add(
        self, parent: str, child: str, stamp: float, translation: Sequence[float], rotation: Sequence[float]
    ) -> None:
        """Record one sample of a dynamic link T_parent_child at time ``stamp``."""
        self.add_many(parent, child, [stamp], [translation], [rotation])

    def add_many(
        self, parent: str, child: str, stamps: Iterable[float], translations: npt.ArrayLike, rotations: npt.ArrayLike
    ) -> None:
        """Record samples (n,) / (n, 3) / (n, 4) of a dynamic link; order does not matter, repeated stamps count once."""
        edge = self._edge(parent, child)
        stamps = np.asarray(list(stamps) if not isinstance(stamps, np.ndarray) else stamps, dtype=float)
        ok = _clean(translations, rotations) & np.isfinite(stamps)
        edge.invalid += int(np.count_nonzero(~ok))
        edge.append(
            stamps[ok],
            np.asarray(translations, dtype=float).reshape(-1, 3)[ok],
            np.asarray(rotations, dtype=float).reshape(-1, 4)[ok],
        )

    # -- inspection ----------------------------------------------------------------------------
    @property
    def frames(self) -> list[str]:
        """Return every frame id (normalized), sorted."""
        return sorted(self._adjacency)

    def has_frame(self, frame: str) -> bool:
        """Return True when ``frame`` appears in some link."""
        return normalize_frame(frame) in self._adjacency

    def has_parent(self, frame: str) -> bool:
        """Return True when some link has ``frame`` as its child (False for roots and unknown frames)."""
        frame = normalize_frame(frame)
        return any(c == frame for (_, c) in self._edges)

    def edges(self) -> list[EdgeInfo]:
        """Return every link, sorted by (parent, child)."""
        out = []
        for (parent, child), e in sorted(self._edges.items()):
            first, last = e.span()
            out.append(EdgeInfo(parent, child, e.static, e.count(), first, last, e.duplicates, e.invalid))
        return out

    def root_of(self, frame: str) -> str:
        """Return the root of the tree that holds ``frame`` (the frame itself when it has no parent)."""
        frame = normalize_frame(frame)
        seen = {frame}
        while True:
            parents = [p for (p, c) in self._edges if c == frame]
            if not parents or parents[0] in seen:
                return frame
            frame = parents[0]
            seen.add(frame)

    def _missing(self, frame: str, source: str, target: str) -> TransformLookupError:
        present = ", ".join(self.frames) if self.frames else "none: the bag has no /tf or /tf_static messages"
        return TransformLookupError(
            f"cannot connect frame '{source}' to frame '{target}': '{frame}' does not appear in /tf or /tf_static "
            f"(frames present: {present})",
            source=source,
            target=target,
        )

    def chain(self, target: str, source: str) -> list[str]:
        """Return the frames from ``source`` to ``target`` (both included); raise TransformLookupError if unconnected."""
        source, target = normalize_frame(source), normalize_frame(target)
        if source == target:
            return [source]
        for frame in (source, target):
            if frame not in self._adjacency:
                raise self._missing(frame, source, target)
        previous = {source: source}  # frame -> the frame it was reached from (the source: itself)
        queue = deque([source])
        while queue:
            frame = queue.popleft()
            if frame == target:
                break
            for nxt in sorted(self._adjacency[frame]):
                if nxt not in previous:
                    previous[nxt] = frame
                    queue.append(nxt)
        if target not in previous:
            raise TransformLookupError(
                f"cannot connect frame '{source}' to frame '{target}': no chain of /tf or /tf_static transforms "
                f"links them ('{source}' is in the tree rooted at '{self.root_of(source)}', '{target}' in the tree "
                f"rooted at '{self.root_of(target)}')",
                source=source,
                target=target,
            )
        path = [target]
        while path[-1] != source:
            path.append(previous[path[-1]])
        return path[::-1]

    def _links(self, target: str, source: str) -> list[tuple[_Edge, bool]]:
        """Return the links from source to target, each with True when it is walked child -> parent."""
        path = self.chain(target, source)
        out = []
        for a, b in zip(path[:-1], path[1:]):
            edge = self._edges[self._adjacency[a][b]]
            out.append((edge, edge.child == a))
        return out

    def is_static(self, target: str, source: str) -> bool:
        """Return True when every link between the two frames is static."""
        return all(edge.static for edge, _ in self._links(target, source))

    def dynamic_stamps(self, target: str, source: str) -> np.ndarray:
        """Return the sample times of the dynamic link nearest to ``source`` on the chain to ``target`` (empty if none)."""
        for edge, _ in self._links(target, source):
            if not edge.static:
                return edge.arrays()[0].copy()
        return np.zeros(0)

    def span(self, target: str, source: str) -> tuple[float, float]:
        """Return the interval of times over which every dynamic link of the chain has samples (-inf, inf if static)."""
        lo, hi = -np.inf, np.inf
        for edge, _ in self._links(target, source):
            a, b = edge.span()
            lo, hi = max(lo, a), min(hi, b)
        return lo, hi

    # -- lookup --------------------------------------------------------------------------------
    def lookup(
        self, target: str, source: str, times: Sequence[float] | np.ndarray, tolerance: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (R (N, 3, 3), p (N, 3), valid (N,)): T_target_source at each time, composed along the chain.

        ``valid[i]`` is False where a dynamic link of the chain has no samples
        around ``times[i]`` (more than ``tolerance`` seconds before its first or
        after its last sample); R and p hold the nearest sample's value there.
        Raises TransformLookupError naming both frames when they are not connected.
        """
        times = np.atleast_1d(np.asarray(times, dtype=float))
        n = len(times)
        R = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
        p = np.zeros((n, 3))
        valid = np.ones(n, dtype=bool)
        # T_{f_{k+1} f_0} = T_{f_{k+1} f_k} T_{f_k f_0}, walking from source (f_0) to target
        for edge, upward in self._links(target, source):
            Re, pe, ok = edge.at(times, tolerance)  # T_parent_child
            if upward:  # f_k is the child: T_{f_{k+1} f_k} = T_parent_child
                Rs, ps = Re, pe
            else:  # f_k is the parent: T_child_parent = inverse
                Rs = np.transpose(Re, (0, 2, 1))
                ps = -np.einsum("nij,nj->ni", Rs, pe)
            p = np.einsum("nij,nj->ni", Rs, p) + ps
            R = np.einsum("nij,njk->nik", Rs, R)
            valid &= ok
        return R, p, valid
