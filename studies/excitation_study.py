"""The excitation study: does the excitation-aware contact schedule make the EKF's CoM converge faster?

Closed-loop runs on the paper's Traj. 2 with the EKF fed the wrench (commanded,
measured or fused) and its contact-dependent covariance (``CartEKF.step(...,
gamma_cov=...)``); :func:`contact_study` compares schedules over seeds,
:func:`format_table` / :func:`format_paired` print the tables of docs/contacts.md
(``benchmarks/bench_excitation.py`` runs it). Not library API: the planner it
evaluates is `wholebody.contacts.excitation`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from cart.table1 import EstimatingLoop
from wholebody.contacts.allocation import ArmLimits, WrenchAllocator
from wholebody.contacts.excitation import (
    ContactSchedule,
    InputModel,
    WrenchNoise,
    cart_wrench_covariance,
    com_crlb_course,
    default_prior,
    input_model,
    sample_push,
)
from wholebody.contacts.handle import HandleSegment, grasp_map

#: Table I test-5 cart (truth) and the EKF's initial guess used by the study.
STUDY_TRUE_COM = (0.3, 0.15)
STUDY_GUESS = (16.0, 0.3, 0.0, 1.6, 4.0)  # m, dx, dy, I, sigma


@dataclass(frozen=True)
class ConvergenceResult:
    """CoM-estimate convergence of one closed-loop run (histories at the control rate).

    ``com_error``: |(dx, dy) estimate - truth| (m); ``com_std``: the EKF's
    posterior std of (dx, dy); ``com``: the estimate; ``mass_error``: estimate
    minus truth (kg); ``mean_nis``: mean normalized innovation squared (6 when
    consistent).
    """

    label: str
    seed: int
    t: np.ndarray = field(repr=False)
    com: np.ndarray = field(repr=False)
    com_error: np.ndarray = field(repr=False)
    com_std: np.ndarray = field(repr=False)
    mass_error: np.ndarray = field(repr=False)
    mean_nis: float
    tol: float = 0.03

    def _index(self, t: float) -> int:
        return int(min(np.searchsorted(self.t, t - 1e-9), len(self.t) - 1))

    def error_at(self, t: float) -> float:
        """Return the CoM error (m) at time t."""
        return float(self.com_error[self._index(t)])

    def time_below(self, tol: float | None = None) -> float | None:
        """Return the time from which the CoM error stays below tol (None if it ends above)."""
        tol = self.tol if tol is None else tol
        ok = self.com_error < tol
        if not ok[-1]:
            return None
        bad = np.nonzero(~ok)[0]
        return float(self.t[0]) if bad.size == 0 else float(self.t[bad[-1] + 1])

    @property
    def time_to_tol(self) -> float | None:
        """Return the time from which the CoM error stays below ``tol`` (None if never)."""
        return self.time_below()

    @property
    def final_com_error(self) -> float:
        """Return the CoM error at the end (m)."""
        return float(self.com_error[-1])

    @property
    def final_mass_error(self) -> float:
        """Return |mass error| at the end (kg)."""
        return float(abs(self.mass_error[-1]))


class _SensorLoop(EstimatingLoop):
    """Table I's estimating loop (:class:`cart.table1.EstimatingLoop`) with a sensed wrench and one arm.

    Each period the arm applies ``w + e`` (``w`` the allocation of the tracking
    wrench at the scheduled contact, ``e`` the actuation error), the F/T sensor
    reads ``w + e + n``; the EKF's next step is fed
    ``w + K (reading - w)`` (:func:`input_model`) and the covariance of its
    error mapped through the grasp map to {s} (``gamma_cov``, as a density:
    per-period covariance times dt, since the wrench is held over dt).
    """

    def __init__(
        self,
        controller,
        guess,
        config,
        contact: Callable[[float], float],
        handle: HandleSegment,
        model: InputModel,
        sensor: WrenchNoise,
        actuation: WrenchNoise,
        rng,
        n: int,
        substeps: int = 1,
    ) -> None:
        super().__init__(controller, guess, config, contact, n, substeps)
        self.handle, self.rng = handle, rng
        self.gain = model.gains_ee()
        self.cov_in = model.noise.covariance_ee()
        self.std_e = np.sqrt(np.diag(actuation.covariance_ee()))
        self.std_n = np.sqrt(np.diag(sensor.covariance_ee()))
        self.alloc = WrenchAllocator([handle.point(0.0)], ArmLimits(), only_motion_directions=True)
        self.gamma_cov = np.zeros((3, 3))
        self.com_hat = np.zeros((n, 2))
        self.com_std = np.zeros((n, 2))
        self.mass_hat = np.zeros(n)

    def _record(self, params) -> None:
        """Store the CoM estimate, its std and the mass of sample k."""
        self.com_hat[self.k] = (params.dx, params.dy)
        self.com_std[self.k] = self.ekf.params_std()["com"]
        self.mass_hat[self.k] = params.m

    def _apply(self, t: float, x_hat: np.ndarray, gamma_w: np.ndarray) -> np.ndarray:
        """Allocate the tracking wrench to the arm at the scheduled contact; return what the arm applies."""
        th = float(x_hat[2])
        c, s = np.cos(th), np.sin(th)
        gamma_b = np.array([c * gamma_w[0] + s * gamma_w[1], 0.0, gamma_w[2]])
        p = self.handle.point(self.contact(t))
        self.alloc.set_points([p])
        w = self.alloc.solve(gamma_b, raise_on_infeasible=False).wrenches_ee[0]
        draw = self.rng.standard_normal(12)  # always 12 draws: runs differing only in mode/contact share noise
        e = self.std_e * draw[:6]
        n = self.std_n * draw[6:]
        G = grasp_map(p)
        Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        self.gamma_in = Rz @ (G @ (w + self.gain * (e + n)))
        self.gamma_cov = cart_wrench_covariance(p, self.cov_in, th)
        return Rz @ (G @ (w + e))


def study_config(dt: float = 0.01, q_floor: float = 1e-5, q_phi: float = 0.0):
    """Return the EKFConfig of the study: measurement noise of Table I level 0.005, process-noise floor q_floor.

    ``q_floor`` (m^2/s^3, rad^2/s^3) is the model-error floor on the velocities
    (Euler vs RK4 discretisation: it gives mean NIS ~6 with an exact wrench);
    the wrench noise itself enters per step through ``gamma_cov``. ``q_phi``:
    random walk of phi (0: the parameters are constant).
    """
    from cart.ekf import EKFConfig
    from cart.simulate import MeasurementNoise

    meas = MeasurementNoise.from_level(0.005)
    return EKFConfig.from_noise(meas.measurement_std(), q_pos=1e-8, q_vel=q_floor, q_omega=q_floor, q_phi=(q_phi,) * 4)


def com_convergence_traj2(
    contact: Callable[[float], float] | ContactSchedule,
    label: str = "",
    seed: int = 0,
    true_com: tuple[float, float] = STUDY_TRUE_COM,
    tol: float = 0.03,
    duration: float = 30.0,
    dt: float = 0.01,
    noise: WrenchNoise = WrenchNoise(),
    handle: HandleSegment | None = None,
    ekf_input: str = "fused",
    actuation: WrenchNoise = WrenchNoise(),
    q_floor: float = 1e-5,
    q_phi: float = 0.0,
    ekf_substeps: int = 4,
    guess: Sequence[float] = STUDY_GUESS,
) -> ConvergenceResult:
    """Return the CoM convergence of the EKF on Traj. 2 (Table I test 5 cart) with the given contact schedule.

    The robot tracks Traj. 2 with the paper's feedback-linearization/LQR law on
    the EKF estimate and realizes each wrench with one arm at the scheduled
    contact (allocation QP). The arm's wrench has a white error ``actuation``
    in {a}; the F/T sensor at the contact reads it with white noise ``noise``
    in {a}. The EKF is fed the wrench chosen by ``ekf_input``
    (:func:`input_model`) together with the covariance of its error mapped
    through the grasp map (``gamma_cov``). ``ekf_substeps`` Euler predictions
    (``CartEKF.predict``) per control period precede each update: with one
    (``CartEKF.step``) the O(dt) discretisation error biases the parameters
    under wrench noise (docs/contacts.md). ``guess``: the EKF's initial (m, dx,
    dy, I, sigma); its sigma is used as known.
    """
    from cart.params import CartParams
    from cart.trajectories import trajectory_2

    handle = HandleSegment.default() if handle is None else handle
    at = contact.at if isinstance(contact, ContactSchedule) else contact
    model = input_model(ekf_input, noise, actuation)
    traj = trajectory_2(duration)
    truth = _study_truth(true_com)
    n = int(round(duration / dt)) + 1
    rng = np.random.default_rng(seed + 10_000)
    sensing = (at, handle, model, noise, actuation, rng)
    loop = _study_loop(traj, CartParams(*guess), study_config(dt, q_floor, q_phi), sensing, n, ekf_substeps)
    sim = _run_traj2(truth, loop, traj, duration, dt, seed)
    return _convergence(label, seed, sim.true.t, loop, truth, tol)


def _study_truth(true_com: tuple[float, float]):
    """Return the study's true cart (Table I test 5): 20 kg, CoM ``true_com``, I = 20 (1 + 0.36) / 12, sigma 4."""
    from cart.params import CartParams

    return CartParams(20.0, true_com[0], true_com[1], 20.0 * (1.0 + 0.36) / 12.0, 4.0)


def _study_loop(traj, guess, config, sensing: tuple, n: int, substeps: int) -> _SensorLoop:
    """Return the sensing loop tracking ``traj`` by FL/LQR; ``sensing`` = (contact, handle, model, sensor, actuation, rng)."""
    from cart.control import make_controller

    contact, handle, model, sensor, actuation, rng = sensing
    return _SensorLoop(
        make_controller("fl_lqr", traj), guess, config, contact, handle, model, sensor, actuation, rng, n, substeps
    )


def _run_traj2(truth, loop: _SensorLoop, traj, duration: float, dt: float, seed: int):
    """Return the simulation of the true cart under ``loop`` from the start of ``traj`` (Table I noise level 0.005)."""
    from cart.simulate import MeasurementNoise, simulate

    meas = MeasurementNoise.from_level(0.005)
    q0, _, _ = traj.sample(0.0)
    return simulate(truth, loop, duration, dt, q0=q0, noise=meas, rng=np.random.default_rng(seed))


def _convergence(label: str, seed: int, t: np.ndarray, loop: _SensorLoop, truth, tol: float) -> ConvergenceResult:
    """Return the convergence record of ``loop``'s estimates against the ``truth`` at the times ``t``."""
    err = np.hypot(loop.com_hat[:, 0] - truth.dx, loop.com_hat[:, 1] - truth.dy)
    return ConvergenceResult(
        label,
        seed,
        t,
        loop.com_hat,
        err,
        loop.com_std,
        loop.mass_hat - truth.m,
        float(np.nanmean(loop.nis)),
        tol,
    )


@dataclass(frozen=True)
class StudyRow:
    """Summary over seeds of one contact schedule (means ± standard errors over seeds).

    ``error_at``: {t: (mean, se)} of the CoM error |(dx, dy) - truth| (m);
    ``rms_at``: {t: (rms, se)} of the same over seeds (se by the delta method);
    ``crlb_at``: {t: sqrt(trace)} of the CoM Cramér–Rao bound (true
    parameters, the input model's noise, the EKF's prior), what ``rms_at``
    should match for an efficient, unbiased EKF; ``time_below``: {tol: ((mean,
    se), never)} of the time from which the error stays < tol, a run that ends
    above tol counting as the push's duration (``never`` such runs);
    ``post_std``: mean EKF posterior std of (dx, dy) at the end; ``spread``:
    std over seeds of the final (dx, dy) estimate; ``bias``: mean final (dx, dy)
    error; ``crlb``: per-axis CRLB std at the end (m); ``mass``: (mean, se) of
    the final mass error (kg); ``nis``: mean NIS; ``per_seed``: {name: per-seed
    values} of the CoM errors at ``times`` (mm) and of the times below each tol
    (s), for paired comparisons between schedules run on the same seeds.
    """

    label: str
    n: int
    error_at: dict
    rms_at: dict
    crlb_at: dict
    time_below: dict
    post_std: tuple[float, float]
    spread: tuple[float, float]
    bias: tuple[float, float]
    crlb: tuple[float, float]
    mass: tuple[float, float]
    nis: float
    per_seed: dict = field(repr=False, default_factory=dict)


def _mean_se(x: Sequence[float]) -> tuple[float, float]:
    x = np.asarray(x, dtype=float)
    se = float(np.std(x, ddof=1) / np.sqrt(len(x))) if len(x) > 1 else float("nan")  # ddof=1 needs 2 seeds
    return float(np.mean(x)), se


def _rms_se(x: Sequence[float]) -> tuple[float, float]:
    """Return the RMS of x and its standard error (delta method on the mean square)."""
    ms, se = _mean_se(np.square(np.asarray(x, dtype=float)))
    rms = float(np.sqrt(ms))
    return rms, (se / (2.0 * rms) if rms > 0.0 else float("nan"))


def summarize(
    label: str,
    results: Sequence[ConvergenceResult],
    crlb_cov: np.ndarray,
    times: Sequence[float] = (10.0, 20.0, 30.0),
    tols: Sequence[float] = (0.03, 0.01),
    true_com=STUDY_TRUE_COM,
) -> StudyRow:
    """Return the StudyRow of the runs of one schedule; ``crlb_cov`` is com_crlb_course at ``times``."""
    dur = float(results[0].t[-1])
    final = np.array([r.com[-1] for r in results]) - np.asarray(true_com)
    tb, per_seed = {}, {}
    for t in times:
        per_seed[f"CoM err {t:g} s [mm]"] = 1000.0 * np.array([r.error_at(t) for r in results])
    for tol in tols:
        x = [r.time_below(tol) for r in results]
        tb[float(tol)] = (_mean_se([dur if v is None else v for v in x]), sum(v is None for v in x))
        per_seed[f"t(err<{100 * tol:g} cm) [s]"] = np.array([dur if v is None else v for v in x])
    return StudyRow(
        label,
        len(results),
        {float(t): _mean_se([r.error_at(t) for r in results]) for t in times},
        {float(t): _rms_se([r.error_at(t) for r in results]) for t in times},
        {float(t): float(np.sqrt(np.trace(c))) for t, c in zip(times, crlb_cov)},
        tb,
        tuple(float(v) for v in np.mean([r.com_std[-1] for r in results], axis=0)),
        tuple(float(v) for v in (np.std(final, axis=0, ddof=1) if len(final) > 1 else [np.nan, np.nan])),
        tuple(float(v) for v in np.mean(final, axis=0)),
        tuple(float(v) for v in np.sqrt(np.diag(crlb_cov[-1]))),
        _mean_se([r.mass_error[-1] for r in results]),
        float(np.mean([r.mean_nis for r in results])),
        per_seed,
    )


def contact_study(
    schedules: Mapping[str, Callable[[float], float] | ContactSchedule],
    seeds: Sequence[int],
    ekf_input: str = "fused",
    noise: WrenchNoise = WrenchNoise(),
    actuation: WrenchNoise = WrenchNoise(),
    duration: float = 30.0,
    dt: float = 0.01,
    times: Sequence[float] = (10.0, 20.0, 30.0),
    tols: Sequence[float] = (0.03, 0.01),
    **kwargs,
) -> tuple[list[StudyRow], dict]:
    """Return (rows, runs): each schedule on Traj. 2 over the seeds, summarized, and the raw results.

    Every schedule sees the same seeds (common random numbers: the same noise
    draws in {a}), so differences between rows are paired. The CRLB columns use
    the input model's error std, one wrench per ``dt``, the true parameters and
    the EKF's prior. ``kwargs`` go to :func:`com_convergence_traj2`.
    """
    from cart.params import CartParams
    from cart.trajectories import trajectory_2

    truth = CartParams(20.0, STUDY_TRUE_COM[0], STUDY_TRUE_COM[1], 20.0 * 1.36 / 12.0, 4.0)
    guess = CartParams(*STUDY_GUESS)
    model = input_model(ekf_input, noise, actuation)
    samples = sample_push(trajectory_2(duration), dt=dt, duration=duration)
    rows, runs = [], {}
    for label, sched in schedules.items():
        res = [
            com_convergence_traj2(
                sched,
                label,
                s,
                duration=duration,
                dt=dt,
                noise=noise,
                ekf_input=ekf_input,
                actuation=actuation,
                **kwargs,
            )
            for s in seeds
        ]
        crlb = com_crlb_course(samples, sched, truth.phi, times, model.noise, default_prior(guess.phi))
        runs[label] = res
        rows.append(summarize(label, res, crlb, times, tols))
    return rows, runs


def format_table(rows: Sequence[StudyRow], scores: Mapping[str, str] | None = None) -> str:
    """Return a markdown table of study rows: CoM errors in mm, times in s, mean ± SE over seeds."""
    times = sorted(rows[0].error_at)
    tols = sorted(rows[0].time_below, reverse=True)
    head = ["contact"] + (["score"] if scores is not None else [])
    head += [f"CoM err {t:g} s [mm]" for t in times] + [f"RMS / CRLB {t:g} s [mm]" for t in times]
    head += [f"t(err<{100 * tol:g} cm) [s]" for tol in tols]
    head += ["spread / EKF std / CRLB at end, dx; dy [mm]", "bias dx; dy [mm]", "mass err [kg]", "NIS"]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    mm = lambda v: f"{1000 * v:.1f}"  # noqa: E731
    for r in rows:
        cells = [r.label] + ([scores.get(r.label, "—")] if scores is not None else [])
        cells += [f"{mm(r.error_at[t][0])} ± {mm(r.error_at[t][1])}" for t in times]
        cells += [f"{mm(r.rms_at[t][0])} ± {mm(r.rms_at[t][1])} / {mm(r.crlb_at[t])}" for t in times]
        for tol in tols:
            (m, se), never = r.time_below[tol]
            cells.append(f"{m:.1f} ± {se:.1f}" + (f" ({never}/{r.n} never)" if never else ""))
        cells.append(
            f"{mm(r.spread[0])} / {mm(r.post_std[0])} / {mm(r.crlb[0])}; "
            f"{mm(r.spread[1])} / {mm(r.post_std[1])} / {mm(r.crlb[1])}"
        )
        cells.append(f"{mm(r.bias[0])}; {mm(r.bias[1])}")
        cells += [f"{r.mass[0]:+.2f} ± {r.mass[1]:.2f}", f"{r.nis:.2f}"]
        out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out)


def format_paired(rows: Sequence[StudyRow], reference: str) -> str:
    """Return a markdown table of paired differences (row minus reference, mean ± SE over the common seeds)."""
    ref = next(r for r in rows if r.label == reference)
    keys = list(ref.per_seed)
    out = ["| contact minus " + reference + " | " + " | ".join(keys) + " |", "|" + "---|" * (len(keys) + 1)]
    for r in rows:
        if r.label == reference:
            continue
        cells = []
        for k in keys:
            d = r.per_seed[k] - ref.per_seed[k]
            m, se = _mean_se(d)
            cells.append(f"{m:+.2f} ± {se:.2f} ({int(np.sum(d > 0))}/{len(d)} > 0)")
        out.append(f"| {r.label} | " + " | ".join(cells) + " |")
    return "\n".join(out)
