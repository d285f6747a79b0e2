"""The paper's §IV tracking experiments in kinematic simulation (straight line and sinusoid, 100 Hz, 60 s).

Desired EE path (world, paper §IV): straight ``X = X0 + 0.09 t`` m; sinusoid
``X = X0 + 0.09 t, Y = Y0 + 1.0 sin(0.1 t)`` m; orientation held at its initial value.

Safety band (paper §VI): a 5.4 m path cannot be followed with the base inside a
fixed disc, so the band is a disc of radius R that slides along the path's axis at
the path's mean speed: ``c(t) = p_base(0) + (0.09 t, 0)``. The base origin (WMRA:
under the drive-axle centre) must stay inside while the EE follows its own path; on
the sinusoid (+-1 m sideways) the arm has to supply the lateral reach the band
denies the base.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from collections.abc import Callable

import numpy as np
import pinocchio as pin

import robots
from robots import profiles
from wholebody.motion.control import ControllerConfig, ResolvedRateController, SafetyBand
from wholebody.errors import WholeBodyError
from wholebody.motion.kinematics import WholeBody, wholebody_for

PATHS = ("line", "sine")
#: Speed of the safety band's centre along world X (m/s): the paths' mean progress, 90 mm/s.
BAND_SPEED = 0.09

#: USF "ready" pose [90, 90, 0, 90, 90, 90, 0] deg has q6 = 90 deg outside the WMRA's +-79 deg
#: limit; we use it with q6 = 30 deg, which leaves room for the wrist to compensate the base turning.
WMRA_INITIAL_ARM_DEG = (90.0, 90.0, 0.0, 90.0, 90.0, 30.0, 0.0)
#: iiwa: elbow bent, wrist bent, all joints >= 30 deg inside their limits.
IIWA_INITIAL_ARM_DEG = (0.0, 45.0, 0.0, -90.0, 0.0, 45.0, 0.0)


def initial_state(wb: WholeBody) -> np.ndarray:
    """Return the experiments' initial reduced state [0, 0, 0, arm q]: the paper's posture of a shipped robot;
    for a robot of a profile its first arm's `push_seed`, else the middle of each arm joint's range."""
    if wb.robot.name == "wmra":
        return np.r_[0.0, 0.0, 0.0, np.radians(WMRA_INITIAL_ARM_DEG)]
    if wb.robot.name == "ridgeback_iiwa":
        return np.r_[0.0, 0.0, 0.0, np.radians(IIWA_INITIAL_ARM_DEG)]
    prof = wb.robot.profile
    seed = prof.push_arm_seed if prof is not None else None
    arm = np.asarray(seed, dtype=float) if seed is not None else _unfolded_mid_range(wb)
    return np.r_[0.0, 0.0, 0.0, arm]


#: the mid-range start is kept when the combined Jacobian's smallest singular value is at least this there
START_SIGMA_MIN = 0.05


def _sigma_min(wb: WholeBody, arm: np.ndarray) -> float:
    return float(np.linalg.svd(wb.combined_jacobian(np.r_[0.0, 0.0, 0.0, arm]), compute_uv=False)[-1])


def _unfolded_mid_range(wb: WholeBody) -> np.ndarray:
    """Return the middle of each arm joint's range, or, where that posture is (near) singular, the best-conditioned
    of a few bent ones: +-2 pi limits put the middle at 0, a stretched arm for UR-type arms (singular on every
    step of a run from it). Candidates: the middle moved 0.6 rad per joint in alternating signs (both ways), then
    16 postures drawn (seed 0) within the middle half of each range; the largest smallest singular value of the
    combined Jacobian wins."""
    lo, hi = np.asarray(wb.arm_lower, dtype=float), np.asarray(wb.arm_upper, dtype=float)
    mid = 0.5 * (lo + hi)
    if _sigma_min(wb, mid) >= START_SIGMA_MIN:
        return mid
    signs = np.where(np.arange(len(mid)) % 2 == 0, 1.0, -1.0)
    inner_lo, inner_hi = lo + 0.25 * (hi - lo), hi - 0.25 * (hi - lo)
    rng = np.random.default_rng(0)
    candidates = [np.clip(mid + s * 0.6 * signs, inner_lo, inner_hi) for s in (1.0, -1.0)]
    candidates += [rng.uniform(inner_lo, inner_hi) for _ in range(16)]
    return max([mid, *candidates], key=lambda arm: _sigma_min(wb, arm))


def path_function(path: str) -> Callable[[float], tuple[np.ndarray, np.ndarray]]:
    """Return t -> (EE offset from the start (3,), EE velocity (3,)) of the paper's path (metres, m/s)."""
    if path == "line":
        return lambda t: (np.array([0.09 * t, 0.0, 0.0]), np.array([0.09, 0.0, 0.0]))
    if path == "sine":
        return lambda t: (np.array([0.09 * t, np.sin(0.1 * t), 0.0]), np.array([0.09, 0.1 * np.cos(0.1 * t), 0.0]))
    raise WholeBodyError(f"unknown path {path!r}; valid: {', '.join(PATHS)}")


@dataclass(frozen=True)
class TrackingResult:
    """A tracking run and its metrics (SI units).

    Attributes:
        robot, path, band_radius: what was run (band_radius None: base free).
        dt, steps: sample time and number of control steps.
        max_position_error_m, rms_position_error_m, max_orientation_error_rad: EE errors over all samples.
        min_joint_limit_margin_rad: smallest distance of any arm joint to its position limit.
        max_joint_speed_ratio, max_wheel_speed_ratio: max |rate| / limit over the run (<= 1 when respected).
        max_band_distance_m: largest distance of the base origin from the band centre (NaN without a band).
        singular_steps, saturated_steps, solver_failures, fallback_steps: counts of flagged steps
            (fallback: the primary QP solver failed and the fallback solver was used).
        t: sample times (steps+1,); x: states (steps+1, 3+n_arm); u: inputs (steps, n_u);
        wheel_rates: (steps, n_wheels); ee_desired, ee_actual: EE positions (steps+1, 3);
        band_center: band centre per sample (steps+1, 2).
    """

    robot: str
    path: str
    band_radius: float | None
    dt: float
    steps: int
    max_position_error_m: float
    rms_position_error_m: float
    max_orientation_error_rad: float
    min_joint_limit_margin_rad: float
    max_joint_speed_ratio: float
    max_wheel_speed_ratio: float
    max_band_distance_m: float
    singular_steps: int
    saturated_steps: int
    solver_failures: int
    fallback_steps: int
    t: np.ndarray = field(repr=False)
    x: np.ndarray = field(repr=False)
    u: np.ndarray = field(repr=False)
    wheel_rates: np.ndarray = field(repr=False)
    ee_desired: np.ndarray = field(repr=False)
    ee_actual: np.ndarray = field(repr=False)
    band_center: np.ndarray = field(repr=False)

    def metrics(self) -> dict:
        """Return the scalar metrics as a JSON-ready dict."""
        keys = (
            "robot",
            "path",
            "band_radius",
            "dt",
            "steps",
            "max_position_error_m",
            "rms_position_error_m",
            "max_orientation_error_rad",
            "min_joint_limit_margin_rad",
            "max_joint_speed_ratio",
            "max_wheel_speed_ratio",
            "max_band_distance_m",
            "singular_steps",
            "saturated_steps",
            "solver_failures",
            "fallback_steps",
        )
        out = {k: getattr(self, k) for k in keys}
        if not np.isfinite(out["max_band_distance_m"]):
            out["max_band_distance_m"] = None
        return out


@dataclass
class _Record:
    """Per-sample arrays of a tracking run (see :class:`TrackingResult`), filled step by step."""

    xs: np.ndarray
    us: np.ndarray
    wheels: np.ndarray
    p_des: np.ndarray
    p_act: np.ndarray
    centers: np.ndarray
    pos_err: np.ndarray
    rot_err: np.ndarray
    flags: np.ndarray = field(default_factory=lambda: np.zeros(4, dtype=int))

    @classmethod
    def empty(cls, wb: WholeBody, n: int, n_x: int) -> _Record:
        """Return an unfilled record of ``n`` steps (``n + 1`` samples) for states of size ``n_x``."""
        return cls(
            xs=np.empty((n + 1, n_x)),
            us=np.empty((n, wb.n_u)),
            wheels=np.empty((n, wb.base.n_wheels)),
            p_des=np.empty((n + 1, 3)),
            p_act=np.empty((n + 1, 3)),
            centers=np.empty((n + 1, 2)),
            pos_err=np.empty(n + 1),
            rot_err=np.empty(n + 1),
        )

    def sample(self, k: int, x: np.ndarray, T_des: pin.SE3, T: pin.SE3, center: np.ndarray) -> None:
        """Store sample ``k``: state, desired and actual EE pose and their errors, band centre."""
        self.xs[k] = x
        self.p_des[k], self.p_act[k] = T_des.translation, T.translation
        self.pos_err[k] = np.linalg.norm(T_des.translation - T.translation)
        self.rot_err[k] = np.linalg.norm(pin.log3(T_des.rotation @ T.rotation.T))
        self.centers[k] = center

    def step(self, k: int, res, wb: WholeBody) -> None:
        """Store the controller's step ``k``: input, wheel rates and its flags."""
        self.flags += (res.singular, res.saturated, not res.solver_ok, res.fallback_used)
        self.us[k] = res.u
        self.wheels[k] = wb.wheel_rates(res.u)


def _track(
    wb: WholeBody,
    ctrl: ResolvedRateController,
    f: Callable[[float], tuple[np.ndarray, np.ndarray]],
    x: np.ndarray,
    n: int,
    dt: float,
    progress: Callable[[int], None] | None,
) -> _Record:
    """Return the record of ``n`` control steps of ``dt`` s tracking the path ``f`` from ``x`` (orientation held)."""
    T0 = wb.ee_placement(x)
    p0, R0 = T0.translation.copy(), T0.rotation.copy()
    base0 = x[:2].copy()
    rec = _Record.empty(wb, n, x.size)
    for k in range(n + 1):
        t = k * dt
        off, vel = f(t)
        T_des = pin.SE3(R0, p0 + off)
        rec.sample(k, x, T_des, wb.ee_placement(x), base0 + np.array([BAND_SPEED * t, 0.0]))
        if k == n:
            break
        res = ctrl.step(
            x, T_des, np.r_[vel, 0.0, 0.0, 0.0], dt, band_center=rec.centers[k], band_center_velocity=(BAND_SPEED, 0.0)
        )
        rec.step(k, res, wb)
        x = wb.integrate(x, res.u, dt)
        if progress is not None:
            progress(k)
    return rec


def _result(wb: WholeBody, path: str, band_radius: float | None, dt: float, n: int, rec: _Record) -> TrackingResult:
    """Return the tracking result (metrics and arrays) of the record ``rec``."""
    q = rec.xs[:, 3:]
    margin = np.minimum(q - wb.arm_lower, wb.arm_upper - q)
    band_dist = np.linalg.norm(rec.xs[:, :2] - rec.centers, axis=1).max() if band_radius is not None else float("nan")
    return TrackingResult(
        robot=wb.robot.name,
        path=path,
        band_radius=band_radius,
        dt=dt,
        steps=n,
        max_position_error_m=float(rec.pos_err.max()),
        rms_position_error_m=float(np.sqrt(np.mean(rec.pos_err**2))),
        max_orientation_error_rad=float(rec.rot_err.max()),
        min_joint_limit_margin_rad=float(margin.min()),
        max_joint_speed_ratio=float(np.max(np.abs(rec.us[:, : wb.n_arm]) / wb.arm_velocity_limit)),
        max_wheel_speed_ratio=float(np.max(np.abs(rec.wheels) / wb.wheel_velocity_limit)),
        max_band_distance_m=float(band_dist),
        singular_steps=int(rec.flags[0]),
        saturated_steps=int(rec.flags[1]),
        solver_failures=int(rec.flags[2]),
        fallback_steps=int(rec.flags[3]),
        t=np.arange(n + 1) * dt,
        x=rec.xs,
        u=rec.us,
        wheel_rates=rec.wheels,
        ee_desired=rec.p_des,
        ee_actual=rec.p_act,
        band_center=rec.centers,
    )


def run_tracking(
    robot: str = "wmra",
    path: str = "line",
    band_radius: float | None = None,
    duration: float = 60.0,
    rate: float = 100.0,
    config: ControllerConfig | None = None,
    wb: WholeBody | None = None,
    x0: np.ndarray | None = None,
    progress: Callable[[int], None] | None = None,
) -> TrackingResult:
    """Return the result of tracking the paper's `path` for `duration` s at `rate` Hz (paper §IV).

    Args:
        robot: "wmra" (differential drive, wheel-rate input), "ridgeback_iiwa" (mecanum, twist input), or any
            registered robot or profile file (.toml) with an arm on a wheeled base (its first arm tracks).
        path: "line" or "sine".
        band_radius: safety band radius (m) around the moving band centre, or None (base free).
        config: controller options (default `ControllerConfig()`).
        wb, x0: whole-body model and initial state (defaults: the shipped robot, `initial_state`).
        progress: called with the step index after every step (e.g. a progress bar).
    """
    if not (duration > 0 and rate > 0):
        raise WholeBodyError("duration and rate must be positive")
    f = path_function(path)
    if wb is None:
        wb = wholebody_for(robots.load(robot), profiles.profile(robot).base_input)
    x = initial_state(wb) if x0 is None else np.asarray(x0, dtype=float)
    band = SafetyBand(band_radius) if band_radius is not None else None
    ctrl = ResolvedRateController(wb, config or ControllerConfig(), band=band)
    dt = 1.0 / rate
    n = int(round(duration * rate))
    rec = _track(wb, ctrl, f, x, n, dt, progress)
    return _result(wb, path, band_radius, dt, n, rec)
