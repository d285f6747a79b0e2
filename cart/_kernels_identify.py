"""Numerical kernels of :mod:`cart.identify` in numpy alone (no ``scipy.signal`` / ``scipy.stats`` import).

``cartpush estimate`` spends most of its start-up importing ``scipy.signal`` (~0.8 s) and
``scipy.stats`` (~0.3 s) for three small functions; these are their numpy equivalents:

- :func:`butter_lowpass_sos`: ``scipy.signal.butter(order, wn, output="sos")`` (even order): analog
  Butterworth prototype, pre-warped bilinear transform, second-order sections ordered like
  ``scipy.signal.zpk2sos`` (the poles nearest the unit circle last, the gain in the first section);
- :func:`sosfiltfilt`: ``scipy.signal.sosfiltfilt(sos, x, axis=0, padlen=...)`` (odd extension, initial
  states from the steady state of a step, forward and backward passes). Each section's recursion is a
  banded lower-triangular system (the transposed-direct-form-II states enter its first two right-hand
  sides) solved for all columns at once by LAPACK's ``dtbtrs`` (:func:`_section_filter`), called through
  ctypes so that it releases the GIL: from ``THREADED_VALUES`` values on, half of the columns are filtered
  on a second thread (each column alone, the same numbers);
- :func:`student_t_quantile`: ``scipy.stats.t.ppf`` for an integer number of degrees of freedom
  (closed-form CDF, Abramowitz & Stegun 26.7.3-4, solved by bisection).

The results agree with scipy's to rounding (tests/cart/test_identify_speed.py compares them).
"""

from __future__ import annotations

import ctypes
import functools
import math
import threading
from collections.abc import Callable

import numpy as np


def butter_lowpass_sos(order: int, wn: float) -> np.ndarray:
    """Return the digital Butterworth low-pass of even ``order`` and cut-off ``wn`` (share of Nyquist) as sos (k, 6)."""
    if order < 2 or order % 2:
        raise ValueError(f"butter_lowpass_sos needs an even order >= 2, got {order}")
    if not 0.0 < wn < 1.0:
        raise ValueError(f"the cut-off must be in (0, 1) of the Nyquist frequency, got {wn}")
    p = -np.exp(1j * np.pi * np.arange(-order + 1, order, 2) / (2 * order))  # analog prototype poles
    warped = 4.0 * math.tan(math.pi * wn / 2.0)  # pre-warp, fs = 2
    p = warped * p
    k = warped**order
    fs2 = 4.0
    pz = (fs2 + p) / (fs2 - p)  # bilinear transform; every zero maps to -1
    k = k * np.real(1.0 / np.prod(fs2 - p))
    upper = pz[np.imag(pz) > 0]  # one pole of each conjugate pair
    order_idx = np.argsort(-np.abs(1.0 - np.abs(upper)), kind="stable")  # farthest from the unit circle first
    sos = np.zeros((order // 2, 6))
    for row, i in enumerate(order_idx):
        p1 = upper[i]
        sos[row] = [1.0, 2.0, 1.0, 1.0, -2.0 * p1.real, p1.real * p1.real + p1.imag * p1.imag]
    sos[0, :3] *= k
    return sos


def _section_zi(sos: np.ndarray) -> np.ndarray:
    """Return the steady-state initial states (sections, 2) for a unit step (``scipy.signal.sosfilt_zi``)."""
    zi = np.empty((len(sos), 2))
    scale = 1.0
    for s, (b0, b1, b2, _, a1, a2) in enumerate(sos):
        i_minus_a = np.array([[1.0 + a1, -1.0], [a2, 1.0]])
        zi[s] = scale * np.linalg.solve(i_minus_a, np.array([b1 - a1 * b0, b2 - a2 * b0]))
        scale *= (b0 + b1 + b2) / (1.0 + a1 + a2)
    return zi


@functools.cache
def _lapack_dtbtrs() -> Callable[..., None]:
    """Return LAPACK's ``dtbtrs`` (the routine ``scipy.linalg.lapack.dtbtrs`` wraps) as a ctypes function.

    The pointer is the one ``scipy.linalg.cython_lapack`` exports; a ctypes call releases the GIL (the f2py
    wrapper keeps it), so the two halves of :func:`sosfiltfilt`'s columns are solved on two cores at once.
    """
    from scipy.linalg import cython_lapack

    capsule = cython_lapack.__pyx_capi__["dtbtrs"]
    get_name = ctypes.PYFUNCTYPE(ctypes.c_char_p, ctypes.py_object)(("PyCapsule_GetName", ctypes.pythonapi))
    get_pointer = ctypes.PYFUNCTYPE(ctypes.c_void_p, ctypes.py_object, ctypes.c_char_p)(
        ("PyCapsule_GetPointer", ctypes.pythonapi)
    )  # own prototypes: ctypes.pythonapi's shared ones are left as they are
    address = get_pointer(capsule, get_name(capsule))
    int_p = ctypes.POINTER(ctypes.c_int)
    char_p, double_p = ctypes.c_char_p, ctypes.c_void_p
    signature = ctypes.CFUNCTYPE(
        None, char_p, char_p, char_p, int_p, int_p, int_p, double_p, int_p, double_p, int_p, int_p
    )
    return signature(address)


def _solve_lower_band(band: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve the lower-triangular banded system of ``band`` (bands, n; Fortran order) for the columns of ``rhs``
    (n, c; Fortran order, overwritten and returned) with LAPACK's ``dtbtrs`` (uplo L, no transpose, non-unit)."""
    n, c = rhs.shape
    info = ctypes.c_int(0)
    _lapack_dtbtrs()(
        b"L", b"N", b"N", ctypes.c_int(n), ctypes.c_int(band.shape[0] - 1), ctypes.c_int(c),
        band.ctypes.data, ctypes.c_int(band.shape[0]), rhs.ctypes.data, ctypes.c_int(max(n, 1)), info,
    )  # fmt: skip
    if info.value != 0:
        raise np.linalg.LinAlgError(f"banded triangular solve failed (LAPACK info {info.value})")
    return rhs


def _section_filter(section: np.ndarray, x: np.ndarray, z0: np.ndarray) -> np.ndarray:
    """Return one biquad section applied along axis 0 of x (n, c) from the initial states z0 (2, c).

    The section's recursion y[i] + a1 y[i-1] + a2 y[i-2] = b0 x[i] + b1 x[i-1] + b2 x[i-2] is a
    lower-triangular banded system (bandwidth 2); the transposed-direct-form-II states z0 enter its
    first two right-hand sides. LAPACK's banded triangular solve (``dtbtrs``) runs the recursion.
    """
    b0, b1, b2, _, a1, a2 = section
    n = len(x)
    rhs = np.empty(x.shape, order="F")  # LAPACK's layout
    np.multiply(b0, x, out=rhs)
    if n > 1:
        tmp = np.empty((n - 1,) + x.shape[1:], order="F")
        rhs[1:] += np.multiply(b1, x[:-1], out=tmp)
        rhs[2:] += np.multiply(b2, x[:-2], out=tmp[: n - 2])
        rhs[1] += z0[1]
    rhs[0] += z0[0]
    band = np.empty((3, n), order="F")  # LAPACK's layout
    band[0] = 1.0
    band[1] = a1
    band[2] = a2
    return _solve_lower_band(band, rhs)


def sosfilt(sos: np.ndarray, x: np.ndarray, zi: np.ndarray) -> np.ndarray:
    """Return the cascade of second-order sections applied along axis 0 of x (n, c); zi (sections, 2, c)."""
    y = x
    for section, z0 in zip(sos, zi):
        y = _section_filter(section, y, z0)
    return y


#: :func:`sosfiltfilt` filters half of the columns on a second thread when there are at least this many values.
THREADED_VALUES = 20000


def _filtfilt_columns(sos: np.ndarray, flat: np.ndarray, padlen: int) -> np.ndarray:
    """Return the zero-phase filtering of the columns of ``flat`` (n, c), odd extension of ``padlen`` samples."""
    n = len(flat)
    ext = np.empty((n + 2 * padlen, flat.shape[1]), order="F")  # column-major: each column's recursion is contiguous
    ext[padlen : padlen + n] = flat
    if padlen > 0:
        np.subtract(2.0 * flat[0], flat[padlen:0:-1], out=ext[:padlen])
        np.subtract(2.0 * flat[-1], flat[-2 : -padlen - 2 : -1], out=ext[padlen + n :])
    zi = _section_zi(sos)[:, :, None]
    y = sosfilt(sos, ext, zi * ext[0])
    y = sosfilt(sos, y[::-1], zi * y[-1])[::-1]
    if padlen > 0:
        y = y[padlen:-padlen]
    return y


def _filtfilt_two_threads(sos: np.ndarray, flat: np.ndarray, padlen: int) -> np.ndarray:
    """Return :func:`_filtfilt_columns` of ``flat`` with its last columns filtered on a second thread (each
    column's numbers are computed alone, in the same operations: the same result as one pass)."""
    half = flat.shape[1] // 2
    result: list[np.ndarray | BaseException] = []
    _lapack_dtbtrs()  # looked up once, here, before the second thread needs it

    def second() -> None:
        try:
            result.append(_filtfilt_columns(sos, flat[:, half:], padlen))
        except BaseException as exc:  # noqa: BLE001 - re-raised on the calling thread
            result.append(exc)

    worker = threading.Thread(target=second, name="cartpush-filter")
    worker.start()
    try:
        first = _filtfilt_columns(sos, flat[:, :half], padlen)
    finally:
        worker.join()
    if isinstance(result[0], BaseException):
        raise result[0]
    return np.concatenate([first, result[0]], axis=1)


def sosfiltfilt(sos: np.ndarray, x: np.ndarray, padlen: int) -> np.ndarray:
    """Return the zero-phase (forward-backward) filtering of x along axis 0, odd extension of ``padlen`` samples."""
    x = np.asarray(x, float)
    flat = x.reshape(len(x), -1)
    n = len(flat)
    if padlen >= n:
        raise ValueError(f"padlen {padlen} must be less than the signal length {n}")
    if flat.shape[1] >= 2 and flat.size >= THREADED_VALUES:
        y = _filtfilt_two_threads(sos, flat, padlen)
    else:
        y = _filtfilt_columns(sos, flat, padlen)
    return np.ascontiguousarray(y).reshape(x.shape)


def median(x: np.ndarray | list) -> np.floating:
    """Return ``np.median(x)`` (all elements), the same number, from one partition of a float64 array.

    ``np.median`` partitions about both middle elements and about the last one (its NaN check); here the
    array is partitioned about the upper middle only: the lower middle is the largest element before it,
    and partitioning puts any NaN in the upper part, which then gives NaN as ``np.median`` does. 3-5 times
    faster on long arrays (the estimate path takes medians of whole 200 Hz logs). Other dtypes go to ``np.median``.
    """
    a = np.asarray(x)
    if a.dtype != np.float64 or a.size == 0:
        return np.median(a)
    a = a.ravel()
    h = len(a) // 2
    p = np.partition(a, h)
    if np.isnan(p[h:]).any():
        return np.float64(np.nan)
    if len(a) % 2:
        return p[h]
    return (p[:h].max() + p[h]) / 2.0


def median_columns(x: np.ndarray) -> np.ndarray:
    """Return ``np.median(x, axis=0)`` of a 2-D array, the same numbers, column by column (:func:`median`)."""
    a = np.asarray(x)
    if a.ndim != 2 or a.dtype != np.float64 or a.shape[0] == 0:
        return np.median(a, axis=0)
    return np.array([median(a[:, k]) for k in range(a.shape[1])])


def _student_t_two_sided(t: float, dof: int) -> float:
    """Return P(|T| < t) of Student's t with integer ``dof`` (Abramowitz & Stegun 26.7.3-4)."""
    theta = math.atan(t / math.sqrt(dof))
    c2 = math.cos(theta) ** 2
    if dof % 2:  # odd
        if dof == 1:
            return 2.0 * theta / math.pi
        term, total = 1.0, 1.0
        for k in range(1, (dof - 1) // 2):
            term *= c2 * (2 * k) / (2 * k + 1)
            total += term
        return 2.0 / math.pi * (theta + math.sin(theta) * math.cos(theta) * total)
    term, total = 1.0, 1.0
    for k in range(1, dof // 2):
        term *= c2 * (2 * k - 1) / (2 * k)
        total += term
    return math.sin(theta) * total


def student_t_quantile(p: float, dof: int) -> float:
    """Return the ``p`` quantile (0.5 < p < 1) of Student's t with integer ``dof`` >= 1 (bisection)."""
    if not (0.5 < p < 1.0) or dof < 1 or int(dof) != dof:
        raise ValueError(f"student_t_quantile needs 0.5 < p < 1 and an integer dof >= 1, got p={p}, dof={dof}")
    return bisect_increasing(lambda t: _student_t_two_sided(t, int(dof)), 2.0 * p - 1.0, 1e-14)


def bisect_increasing(f, target: float, rel_tol: float) -> float:
    """Return x >= 0 with f(x) = target for an increasing f with f(0) <= target (bracket by doubling, then bisect)."""
    lo, hi = 0.0, 1.0
    while f(hi) < target:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if f(mid) < target:
            lo = mid
        else:
            hi = mid
        if hi - lo <= rel_tol * hi:
            break
    return 0.5 * (lo + hi)
