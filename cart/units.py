"""Unit mistakes recognised from the physics of a pushed cart, refused with the fix named.

docs/log_format.md asks for SI units and radians. Three mistakes are common and silently give absurd
parameters (a 50 kg cart estimated at 0.06 kg from positions in millimetres); each shows in the
kinematics of the pose stream, whatever the cart:

- time in milliseconds (or micro-, nanoseconds): the pose's median sample interval is beyond
  ``MAX_POSE_PERIOD`` (motion capture runs at 10 Hz or more); the unit named is the one that brings it
  below;
- positions in millimetres (or centimetres, inches): the cart's typical speed (the 90th percentile over
  0.1 s windows, so a glitch does not count) is beyond ``MAX_TYPICAL_SPEED``; with a pose sampled
  faster than ``MIN_POSE_PERIOD`` (no motion capture does) that is time in minutes;
- forces in lbf (or kgf): invisible in the data (every parameter scales by one factor); a unit the
  log's metadata or header declares is checked (:func:`check_declared_units`);
- heading in degrees: the heading turns about 57 times faster than the direction of travel (a cart
  rolls along its heading: paper eq. 3), or its typical yaw rate is beyond ``MAX_TYPICAL_YAW_RATE``;
- torque in N mm: the torque about {b}'s origin is at most the force times the distance from {b} to where
  it is applied (a handle or an end effector on the cart); a torque whose scale needs a lever arm beyond
  ``MAX_LEVER_ARM`` (:func:`_torque_scale`) is in N mm;
- a wrench in the cart frame {b} instead of the world frame {s} (:func:`check_wrench_frame`): on a log
  the model does not fit, read in {b} and rotated by theta the forward row's residual variance drops below
  ``FRAME_VARIANCE_SHARE`` of its value as written.

:func:`check_units` raises :class:`UnitsError` (exit code 2 on the command line) naming the fix.
"""

from __future__ import annotations

import math
import re

import numpy as np

from cart._kernels_identify import median
from cart.errors import CartError
from cart.streams import Streams

MAX_POSE_PERIOD = 0.5  # s
MIN_POSE_PERIOD = 1e-3  # s: no motion capture samples the pose faster than 1 kHz
MAX_TYPICAL_SPEED = 8.0  # m/s, 90th percentile: no pushed cart moves that fast most of the time
MAX_TYPICAL_YAW_RATE = 12.0  # rad/s, 90th percentile
#: Share of moving, turning windows whose heading rate / travel-direction rate is near 180 / pi.
DEGREE_SHARE = 0.6
#: m: the torque's lever arm beyond which tau is not in N m: ten times the half-size of the largest cart
#: (a hospital bed's 1 m, `cart.estimate_report.MAX_HALF_SIZE`); N mm make a 1 cm arm read 10 m.
MAX_LEVER_ARM = 10.0
#: Percentile of |tau| and |F| compared by :func:`_torque_scale` (robust to glitches and brief couples).
LEVER_PERCENTILE = 95.0


#: Share of the forward residual variance below which the wrench read in {b} fits so much better that it is in {b}.
FRAME_VARIANCE_SHARE = 0.5
#: The same share when the {b} reading fits only as slow sensor noise (`check_wrench_frame`): a fourfold drop.
FRAME_SLOW_SHARE = 0.25
#: Chi-square drop (over the fit's independent samples) by which reading the wrench in {b} must fit better for a warning.
FRAME_WARN_CHI2 = 10.0


class UnitsError(CartError):
    """The log is not in SI units / radians (names the column and the conversion)."""


def _windows(t: np.ndarray, span: float) -> int:
    """Return the number of samples in about ``span`` seconds (at least 1)."""
    med = float(median(np.diff(t)))
    return max(1, int(math.ceil(span / med))) if med > 0 else 1


def _travel_vs_heading(t: np.ndarray, q: np.ndarray, w: int) -> float:
    """Return the share of moving, turning windows where the heading turns ~57x the direction of travel."""
    d = q[w:] - q[:-w]
    dist = np.hypot(d[:, 0], d[:, 1])
    moving = dist > 10.0 * median(np.abs(np.diff(q[:, :2], axis=0))) + 1e-12
    psi = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    dpsi = psi[w:] - psi[:-w]
    dth = q[2 * w :, 2] - q[w:-w, 2]  # heading change over the same stretch (pose instants w..2w)
    ok = moving[w:] & moving[:-w] & (np.abs(dpsi) > 0.05)
    if ok.sum() < 10:
        return 0.0
    ratio = dth[ok] / dpsi[ok]
    return float(np.mean((ratio > 180.0 / math.pi / 1.5) & (ratio < 180.0 / math.pi * 1.5)))


def _heading_fit(t: np.ndarray, q: np.ndarray, w: int) -> tuple[float, float]:
    """Return the median |sin(travel direction - heading)| on moving windows, heading as is and from degrees.

    A rolling cart travels along its heading (or against it when pulled): near 0 for the right unit.
    """
    d = q[w:, :2] - q[:-w, :2]
    dist = np.hypot(d[:, 0], d[:, 1])
    moving = dist > 10.0 * median(np.abs(np.diff(q[:, :2], axis=0))) + 1e-12
    if moving.sum() < 10:
        return 0.0, 1.0
    psi = np.arctan2(d[moving, 1], d[moving, 0])
    th = 0.5 * (q[w:, 2] + q[:-w, 2])[moving]
    return float(median(np.abs(np.sin(psi - th)))), float(median(np.abs(np.sin(psi - np.radians(th)))))


def _time_unit(period: float) -> tuple[str, float]:
    """Return the time unit (name, factor to seconds) that brings the pose period to ``MAX_POSE_PERIOD`` or less."""
    for unit, factor in (("milliseconds", 1e3), ("microseconds", 1e6)):
        if period / factor <= MAX_POSE_PERIOD:
            return unit, factor
    return "nanoseconds", 1e9


#: Heading range (rad) over which a pushed cart's world-frame wrench cannot keep a column exactly constant.
MIN_TURN_FOR_CONSTANT = 0.5
#: A wrench column whose spread is at most this share of the wrench's largest value is numerically constant (a
#: torque of 1e-300 N m beside forces of newtons: no sensor's reading, and LAPACK's scaling fails on it).
NUMERICALLY_CONSTANT = 1e-12


def _constant_wrench_column(streams: Streams, source: str) -> None:
    """Raise :class:`UnitsError` when a wrench column is constant (to ``NUMERICALLY_CONSTANT`` of the wrench) over the
    log while the cart turns.

    A sensor's reading is never exactly constant (noise); a world-frame force that keeps one component
    constant while the heading turns by ``MIN_TURN_FOR_CONSTANT`` or more is not a push: the column was not
    recorded (a sensor with fewer axes, or a column filled with a constant).
    """
    g = streams.wrench.values
    if len(g) < 5 or float(np.ptp(streams.pose.values[:, 2])) < MIN_TURN_FOR_CONSTANT:
        return
    scale = float(np.max(np.abs(g)))
    for k, name in enumerate(("fx", "fy", "tau")):
        spread = float(np.ptp(g[:, k]))
        if spread <= NUMERICALLY_CONSTANT * scale:
            what = (
                f"is {float(g[0, k]):g} on every row"
                if spread == 0.0
                else (
                    f"stays within {spread:.3g} of {float(g[0, k]):.3g} (numerically constant against the wrench's "
                    f"{scale:.3g})"
                )
            )
            raise UnitsError(
                f"{source}: column {name} {what} while the cart turns by "
                f"{float(np.ptp(streams.pose.values[:, 2])):.3g} rad: it was not recorded (a sensor with fewer "
                "axes?); LOG_FORMAT needs fx, fy (world frame) and tau measured"
            )


def lever_arm(wrench: np.ndarray) -> float:
    """Return the lever arm (m) the wrench's scale implies: the ``LEVER_PERCENTILE`` of |tau| over that of |F|.

    ``wrench``: (n, 3) rows (fx, fy, tau). A push applied at r from {b}'s origin makes tau = r x F, so
    |tau| <= |r| |F| on every sample and the ratio of the two percentiles is at most |r| (order statistics
    keep the inequality); a high percentile, not the maximum, so that a glitch or a brief couple (two hands
    turning the cart with little net force) does not set it. Infinite when the force is zero throughout.
    """
    force = float(np.percentile(np.hypot(wrench[:, 0], wrench[:, 1]), LEVER_PERCENTILE))
    torque = float(np.percentile(np.abs(wrench[:, 2]), LEVER_PERCENTILE))
    return torque / force if force > 0.0 else (math.inf if torque > 0.0 else 0.0)


def _torque_scale(streams: Streams, source: str) -> None:
    """Raise :class:`UnitsError` when tau needs a lever arm beyond ``MAX_LEVER_ARM`` (:func:`lever_arm`).

    The torque about {b}'s origin is the force's moment about it: the force is applied at the cart's handle
    or an end effector, within a cart's size of {b} (a metre or two); a lever arm of tens of metres is not a
    cart: tau is in N mm (x1000), and read as it is the yaw inertia comes out 1000 times too large with the
    model fitting as well. A log whose force is zero throughout has no arm to compare (nothing is refused).
    """
    g = streams.wrench.values
    if len(g) < 5:
        return
    arm = lever_arm(g)
    if math.isfinite(arm) and arm > MAX_LEVER_ARM:
        raise UnitsError(
            f"{source}: |tau| is {arm:.4g} m times |F| ({LEVER_PERCENTILE:g}th percentiles), a lever arm no cart "
            f"has (at most {MAX_LEVER_ARM:g} m): tau looks like N mm (x1000); divide tau by 1000 (LOG_FORMAT: N m)"
        )


def check_units(streams: Streams, source: str = "<memory>") -> None:
    """Raise :class:`UnitsError` when the pose stream's kinematics say time, positions or heading are not SI,
    a wrench column was not recorded (:func:`_constant_wrench_column`) or tau is in N mm (:func:`_torque_scale`)."""
    t, q = streams.pose.t, streams.pose.values
    if len(t) < 5:
        return
    _constant_wrench_column(streams, source)
    _torque_scale(streams, source)
    period = float(median(np.diff(t)))
    if period > MAX_POSE_PERIOD:
        unit, factor = _time_unit(period)
        raise UnitsError(
            f"{source}: the pose is sampled every {period:.4g} s (median): time looks like {unit}; "
            f"divide t by {factor:g} (LOG_FORMAT: seconds)"
        )
    w = _windows(t, 0.1)
    if len(t) <= 3 * w:
        return
    span = t[w:] - t[:-w]
    speed = np.hypot(*((q[w:, :2] - q[:-w, :2]) / span[:, None]).T)
    typical = float(np.percentile(speed, 90))
    if typical > MAX_TYPICAL_SPEED or float(np.percentile(speed, 98)) > 2.5 * MAX_TYPICAL_SPEED:
        if period < MIN_POSE_PERIOD <= 60.0 * period:  # a pose faster than motion capture runs, at 60x the speed
            raise UnitsError(
                f"{source}: the pose is sampled every {period:.3g} s and the cart moves at {typical:.4g} m/s "
                "typically: time looks like minutes; multiply t by 60 (LOG_FORMAT: seconds)"
            )
        raise UnitsError(
            f"{source}: the cart's typical speed is {typical:.4g} m/s: positions look like millimetres, "
            "centimetres or inches; divide x, y by 1000 or 100, or multiply them by 0.0254 (LOG_FORMAT: metres)"
        )
    yaw_rate = float(np.percentile(np.abs(q[w:, 2] - q[:-w, 2]) / span, 90))
    share = _travel_vs_heading(t, q, w)
    as_is, as_degrees = _heading_fit(t, q, w)
    if as_is > 0.3 and as_degrees < 0.1:
        share = 1.0  # the cart travels along its heading only when the heading is read in degrees
    if yaw_rate > MAX_TYPICAL_YAW_RATE or share > DEGREE_SHARE:
        raise UnitsError(
            f"{source}: the heading turns {'at ' + format(yaw_rate, '.4g') + ' rad/s typically' if yaw_rate > MAX_TYPICAL_YAW_RATE else 'about 57 times faster than the direction of travel'}: "
            "theta looks like degrees (or gradians); multiply theta by pi/180 (or pi/200) (LOG_FORMAT: radians)"
        )


#: Units a log's metadata may declare that LOG_FORMAT does not use: token -> (quantity, columns, factor to SI).
NON_SI_UNITS: dict[str, tuple[str, str, float]] = {
    "lbf": ("force", "fx, fy", 4.4482216),
    "lb": ("force", "fx, fy", 4.4482216),
    "lbs": ("force", "fx, fy", 4.4482216),
    "pound": ("force", "fx, fy", 4.4482216),
    "pounds": ("force", "fx, fy", 4.4482216),
    "kgf": ("force", "fx, fy", 9.80665),
    "kn": ("force", "fx, fy", 1000.0),
    "mn": ("force", "fx, fy", 1e-3),
    "mm": ("length", "x, y", 1e-3),
    "cm": ("length", "x, y", 1e-2),
    "inch": ("length", "x, y", 0.0254),
    "inches": ("length", "x, y", 0.0254),
    "ft": ("length", "x, y", 0.3048),
    "feet": ("length", "x, y", 0.3048),
    "deg": ("angle", "theta", math.pi / 180.0),
    "degree": ("angle", "theta", math.pi / 180.0),
    "degrees": ("angle", "theta", math.pi / 180.0),
    "grad": ("angle", "theta", math.pi / 200.0),
    "gon": ("angle", "theta", math.pi / 200.0),
    "ms": ("time", "t", 1e-3),
    "us": ("time", "t", 1e-6),
    "ns": ("time", "t", 1e-9),
    "min": ("time", "t", 60.0),
    "minutes": ("time", "t", 60.0),
}


def check_declared_units(metadata: dict[str, str], source: str = "<memory>") -> None:
    """Raise :class:`UnitsError` when a ``# ...unit...: value`` metadata line declares a unit LOG_FORMAT does not use.

    A force scale cannot be seen in the data: forces in lbf (or kgf) scale the mass, the inertia and the
    dampings by one factor and leave every kinematic check and the model's fit unchanged (a 50 kg cart
    reads as 11.2 kg). What the log says of its own units is then the only evidence: a metadata key that
    contains "unit" (``units``, ``force_unit``, ``fx_units``, ...) whose value names a unit of
    ``NON_SI_UNITS`` as a word is refused with the conversion named. Other metadata is free text.
    """
    for key, value in metadata.items():
        if "unit" not in key.lower():
            continue
        words = re.findall(r"[a-z]+", value.lower().replace("\u00b5s", "us").replace("\u00b0", " deg "))
        for word in words:
            if word in NON_SI_UNITS:
                quantity, columns, factor = NON_SI_UNITS[word]
                header = key == "units (header)"  # `cart.logs.read_log`: units in the header's column names
                where = f"the header row's units ({value})" if header else f"the metadata line '# {key}: {value}'"
                raise UnitsError(
                    f"{source}: {where} declare{'' if header else 's'} {quantity} in {word}; LOG_FORMAT "
                    f"needs SI units and radians: multiply {columns} by {factor:.8g}"
                    + (" (and tau into N m)" if quantity in ("force", "length") else "")
                    + (" and name the columns without units" if header else " and remove or correct that line")
                )


def check_wrench_frame(source: str, ratio: tuple[float, float], cart_frame: tuple[float, float, float] | None) -> None:
    """Raise :class:`UnitsError` when the log's wrench is in the cart frame {b} rather than the world frame {s}.

    ``ratio``: the least-squares fit's residual ratio (forward, yaw) on the log as written; ``cart_frame``:
    (forward residual ratio, mass) of the same regression with (fx, fy) read in {b}, None when the model fits
    (``Identification.cart_frame``, :func:`cart.identify.identify`). Only a log the model does not fit is
    checked: read in {b}, the forward row's residual variance (its ratio to the noise, squared) must drop below
    ``FRAME_VARIANCE_SHARE`` of the written reading's, and the forward row must fit (its ratio within
    :data:`cart.identify.FIT_RATIO`), for the log to be refused. A cart that hardly turns reads alike in both
    frames and is never refused; the torque is the same in both. A misfit of another cause that the {b} reading
    lowers but does not explain (a load put in mid-log: MuJoCo load-change seed 2202, 50.6 -> 79.3 kg, forward
    residual 9.81x the noise as logged, 6.4x read in {b}) is left to :func:`wrench_frame_warning`.

    Under slow (coloured) F/T noise the {b} reading may fit only as the logged one can, with its excess below a
    quarter of the cut-off (``cart_frame``'s third entry within FIT_RATIO, as :func:`cart.identify._slow_excess`
    reads a fit); it is then refused when its residual variance drops below ``FRAME_SLOW_SHARE`` of the logged
    reading's (an outside tester's AR(1)-noise cart, 37.0 kg: 5.09x as logged, 1.63x read in {b}) and the torque
    row, the same in both readings, fits: a yaw misfit says the log holds something a frame does not explain
    (coloured-noise seed 5101 with a random-walk F/T offset, 17.1 kg, in {s}: 6.43x and 4.38x as logged, 2.55x
    read in {b}).
    """
    from cart.identify import FIT_RATIO

    if cart_frame is None or not all(math.isfinite(r) for r in (*ratio, *cart_frame)):
        return
    other, m_other, other_fast = cart_frame
    share = (other / ratio[0]) ** 2
    fits_as_white = share < FRAME_VARIANCE_SHARE and other <= FIT_RATIO
    fits_as_slow = share < FRAME_SLOW_SHARE and other_fast <= FIT_RATIO and ratio[1] <= FIT_RATIO
    if fits_as_white or fits_as_slow:
        raise UnitsError(
            f"{source}: the wrench (fx, fy) looks expressed in the cart frame {{b}}, not in the world frame "
            f"{{s}} that LOG_FORMAT requires: read as {{b}} and rotated by theta, the forward residual is "
            f"{other:.3g}x the noise instead of {ratio[0]:.3g}x (m = {m_other:.4g} kg so read); "
            "rotate fx, fy into {s} (fx_s = cos(theta) fx - sin(theta) fy, "
            "fy_s = sin(theta) fx + cos(theta) fy)"
        )


def check_torque_origin(source: str, ratio: tuple[float, float], origin: float | None) -> None:
    """Raise :class:`UnitsError` when the log's torque is taken about the world origin, not about {b}'s origin.

    ``ratio``: the fit's residual ratio (forward, yaw) as logged; ``origin``: the yaw ratio with the torque
    moved to {b}'s origin (tau - (x fy - y fx); ``Identification.torque_origin``), None when the model fits.
    Refused when, moved, the yaw row fits (its ratio within :data:`cart.identify.FIT_RATIO`, the verdict's
    bound) and its residual variance drops below ``FRAME_VARIANCE_SHARE`` of the logged reading's. A misfit
    of another cause (a load put in mid-log: MuJoCo load-change seed 802, yaw 7.63x the noise as logged, 5.14x
    moved) may also drop when moved, but does not fit: :func:`torque_origin_warning` names the doubt.
    """
    from cart.identify import FIT_RATIO

    if not _origin_drops(ratio, origin) or origin is None or origin > FIT_RATIO:
        return
    raise UnitsError(
        f"{source}: the torque looks taken about the world origin, not about the cart's origin {{b}} that "
        f"LOG_FORMAT requires: moved to {{b}}, the yaw residual is {origin:.3g}x the noise instead of "
        f"{ratio[1]:.3g}x; subtract the force's moment at the cart's position (tau_b = tau - (x fy - y fx))"
    )


def _origin_drops(ratio: tuple[float, float], origin: float | None) -> bool:
    """Return True when moving the torque to {b}'s origin drops the yaw residual variance below the share."""
    if origin is None or not all(math.isfinite(r) for r in (*ratio, origin)):
        return False
    return origin**2 < FRAME_VARIANCE_SHARE * ratio[1] ** 2


def torque_origin_warning(ratio: tuple[float, float], origin: float | None) -> str | None:
    """Return a warning when the torque moved to {b}'s origin fits better than as logged but still misfits.

    The case :func:`check_torque_origin` does not refuse: the logged torque may be about the world origin
    with another effect on top, or another effect's misfit is lowered by the moved moment.
    """
    if not _origin_drops(ratio, origin):
        return None
    return (
        f"the torque may be taken about the world origin instead of the cart's origin {{b}}: moved to {{b}} "
        f"(tau - (x fy - y fx)), the yaw residual is {origin:.3g}x the noise instead of {ratio[1]:.3g}x, but the "
        "model misfits either way; check the logger's reference point, and run `cartpush diagnose`"
    )


def wrench_frame_warning(
    ratio: tuple[float, float], cart_frame: tuple[float, float, float] | None, n_independent: float
) -> str | None:
    """Return a warning when the wrench read in the cart frame {b} fits better than as logged, short of a refusal.

    ``ratio``, ``cart_frame``: as :func:`check_wrench_frame`; ``n_independent``: the fit's independent samples
    (about 2 f_c T: the rows are band-limited to the cut-off f_c). The forward row's residual variance, in
    units of the noise's, summed over the independent samples is a chi-square; read in {b} it must drop by
    more than ``FRAME_WARN_CHI2`` (a likelihood ratio, as a Delta BIC) for the warning. A cart that turns
    little leaves the two readings close and the model fitting both (seed 12007's ``wrench_in_cart_frame07``,
    heading range 1.06 rad: residual ratio 1.13 as logged, 0.98 in {b}, over 99 independent samples; 27.9 kg
    as logged for a 30.0 kg cart, 29.6 kg read in {b}); in {s} the {b} reading fits worse.
    """
    if cart_frame is None or not all(math.isfinite(r) for r in (*ratio, *cart_frame, n_independent)):
        return None
    other, m_other, _ = cart_frame
    drop = n_independent * (ratio[0] ** 2 - other**2)
    if drop <= FRAME_WARN_CHI2 or m_other <= 0.0:
        return None
    return (
        f"the wrench (fx, fy) may be expressed in the cart frame {{b}} instead of the world frame {{s}}: read as {{b}} "
        f"and rotated by theta, the forward residual is {other:.3g}x the noise instead of {ratio[0]:.3g}x (chi-square "
        f"{drop:.0f} lower; m = {m_other:.4g} kg so read); the cart turns too little, or the model misfits either "
        "way, to be sure: check the logger's frame (LOG_FORMAT: fx, fy in {s})"
    )
