"""The 11 simulation tests of the paper's Table I as data, and a runner (paper §III.A).

Each test simulates the 20 kg cart on Traj. 1 or 2 for 30 s at 100 Hz, under a
tracking controller fed by the EKF's state and parameter estimates (with
estimation) or by the same EKF with the parameters frozen at the initial guess
(without estimation). The EKF's R comes from the test's noise level, its Q is
the same for every test (:data:`PROCESS_NOISE`).
"""

from __future__ import annotations

import math
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field, replace
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from cart.control import ControllerName, make_controller
from cart.ekf import CartEKF, EKFConfig
from cart.estimation_metrics import estimation_errors
from cart.errors import CartError, ParameterError
from cart.params import CartParams
from cart.simulate import MeasurementNoise, ParameterChange, min_effort_gamma, simulate
from cart.trajectories import UnicycleTrajectory, trajectory_1, trajectory_2

if TYPE_CHECKING:
    from cart.online_estimator import OnlineLSEstimator

TRUE_MASS = 20.0
#: Inertia about the CoM of the simulated cart: a 1.0 m x 0.6 m box of 20 kg.
TRUE_INERTIA = TRUE_MASS * (1.0**2 + 0.6**2) / 12.0
SIGMA = 4.0
COM_GUESS = (0.3, 0.0)
#: Initial guess of the CoM inertia per kg of guessed mass (radius of gyration ~0.32 m).
INERTIA_GUESS_PER_KG = 0.1
#: Contact point on the handle (in {b}); "vary CP" slides it along the handle. The handle is the
#: shipped cart's: x = -0.15 m, 0.50 m wide (matches CART_HANDLE_X / CART_HANDLE_WIDTH of
#: robots/shopping_cart.py and wholebody/contacts/handle.py; `cart` may not import `robots`).
HANDLE_X = -0.15
HANDLE_HALF_WIDTH = 0.2  # the contact slides over +-0.2 m of the +-0.25 m handle
#: Process noise shared by every test (not tuned per test). The mass random walk (0.01 kg^2/s)
#: lets the variance of m grow during cruise, where m is unobservable (no acceleration), so that a
#: payload change made at cruise (test 11) is learned at the next acceleration or stop; at 0.005 the
#: final stop of test 11 corrects only 88 % of the change (0.62 kg left), from 0.05 up the estimate
#: wanders by > 1 kg during the 20 s of cruise (sweep in docs/cart.md).
PROCESS_NOISE = dict(q_pos=1e-8, q_vel=1e-5, q_omega=1e-5, q_phi=(0.01, 0.005, 0.005, 0.005))
#: The discrete payload changes of test 11 (time s, new mass kg).
MASS_CHANGES_TEST11 = ((10.0, 30.0), (20.0, 25.0))


@dataclass(frozen=True)
class Table1Test:
    """One row of the paper's Table I."""

    test: int
    traj: int
    mass_guess: float
    com: tuple[float, float]
    noise: float
    vary_cp: bool
    mass_changes: tuple[tuple[float, float], ...] = ()
    #: A load added is picked up at rest (dropped in: the cart's momentum is shared, its velocity drops by
    #: m_old / m_new); a load removed leaves with the cart's velocity (lifted out). False: the velocity is
    #: continuous at every change (the load comes and goes moving with the cart; the paper does not say).
    momentum_exchange: bool = False


TESTS: tuple[Table1Test, ...] = (
    Table1Test(1, 1, 16.0, (0.3, 0.0), 0.005, False),
    Table1Test(2, 1, 24.0, (0.3, 0.0), 0.005, False),
    Table1Test(3, 1, 16.0, (0.3, 0.15), 0.005, True),
    Table1Test(4, 2, 16.0, (0.3, 0.0), 0.005, False),
    Table1Test(5, 2, 16.0, (0.3, 0.15), 0.005, False),
    Table1Test(6, 2, 16.0, (0.3, -0.15), 0.005, True),
    Table1Test(7, 2, 16.0, (0.1, 0.0), 0.005, True),
    Table1Test(8, 2, 10.0, (0.3, 0.15), 0.005, False),
    Table1Test(9, 2, 16.0, (0.3, 0.15), 0.05, True),
    Table1Test(10, 2, 16.0, (0.3, 0.15), 0.2, True),
    Table1Test(11, 2, 16.0, (0.3, 0.0), 0.005, True, MASS_CHANGES_TEST11),
)


@dataclass(frozen=True)
class TestRun:
    """Time series of one closed-loop run."""

    t: np.ndarray
    q: np.ndarray  # true pose
    q_desired: np.ndarray
    params_true: np.ndarray  # (N, 5) m, dx, dy, I, sigma
    params_hat: np.ndarray  # (N, 4) m, dx, dy, I (about the CoM)
    nis: np.ndarray
    gamma: np.ndarray
    #: load changes the estimator detected (`cart.online_estimator.LoadChange.as_dict`); () for the EKF
    events: tuple[dict, ...] = ()

    @property
    def position_error(self) -> np.ndarray:
        """Return |p_d - p| of the {b} origin at each sample."""
        return np.hypot(*(self.q_desired[:, :2] - self.q[:, :2]).T)


@dataclass(frozen=True)
class TestResult:
    """Table I metrics of one test (with and without estimation) and its runs.

    Tracking errors (|p_d - p| of the {b} origin over t >= 5 s) in mm, as in
    ``cartpush push``; masses in kg, CoM errors in m, times in s.
    """

    test: int
    mass_error_final_kg: float
    mass_converged_s: float | None
    com_error_final_m: float
    tracking_rms_mm: float
    tracking_rms_no_estimation_mm: float
    tracking_max_after_5s_mm: float
    tracking_max_after_5s_no_estimation_mm: float
    run: TestRun = field(repr=False)
    run_no_estimation: TestRun = field(repr=False)
    #: time-resolved estimation errors of the run with estimation (:func:`estimation_error_metrics`)
    estimation: dict = field(default_factory=dict)
    #: the same test with the online estimator (`cart.online_estimator`) in place of the paper's EKF:
    #: final mass error, its estimation errors and the load changes it detected (empty when not run)
    online: dict = field(default_factory=dict)

    def as_json(self) -> dict:
        """Return the JSON object of `cartpush reproduce --json` for this test."""
        return {
            "test": self.test,
            "mass_error_final_kg": self.mass_error_final_kg,
            "mass_converged_s": self.mass_converged_s,
            "com_error_final_m": self.com_error_final_m,
            "tracking_rms_mm": self.tracking_rms_mm,
            "tracking_rms_no_estimation_mm": self.tracking_rms_no_estimation_mm,
            "tracking_max_after_5s_mm": self.tracking_max_after_5s_mm,
            "tracking_max_after_5s_no_estimation_mm": self.tracking_max_after_5s_no_estimation_mm,
            **self.estimation,
            **({"online": self.online} if self.online else {}),
        }


def describe_test(test: Table1Test) -> str:
    """Return a one-line description of a test from its definition (trajectory, guess, CoM, noise, CP, changes)."""
    parts = [
        f"Traj. {test.traj}",
        f"m guess {test.mass_guess:g} kg",
        f"true CoM ({test.com[0]:g}, {test.com[1]:g}) m",
        f"noise {test.noise * 1000:g} mm",
        "sliding CP" if test.vary_cp else "fixed CP",
    ]
    if test.mass_changes:
        parts.append("mass " + ", ".join(f"{m:g} kg at {t:g} s" for t, m in test.mass_changes))
    return ", ".join(parts)


def true_params(test: Table1Test) -> CartParams:
    """Return the simulated cart of a test (20 kg, CoM of the table)."""
    return CartParams(TRUE_MASS, test.com[0], test.com[1], TRUE_INERTIA, SIGMA)


def guess_params(test: Table1Test) -> CartParams:
    """Return the initial parameter guess of a test (mass of the table, CoM (0.3, 0))."""
    return CartParams(test.mass_guess, COM_GUESS[0], COM_GUESS[1], INERTIA_GUESS_PER_KG * test.mass_guess, SIGMA)


def contact_point(test: Table1Test) -> Callable[[float], tuple[float, float]]:
    """Return the contact point (in {b}) as a function of time: fixed, or sliding along the handle."""
    if test.vary_cp:
        return lambda t: (HANDLE_X, HANDLE_HALF_WIDTH * math.sin(2.0 * math.pi * t / 6.0))
    return lambda t: (HANDLE_X, 0.0)


def ekf_config(noise_level: float, estimate: bool = True, change_detection: bool = False) -> EKFConfig:
    """Return the EKF config of a noise level: R from the noise, the shared Q (optionally change detection)."""
    std = MeasurementNoise.from_level(noise_level).measurement_std()
    return EKFConfig.from_noise(std, estimate_params=estimate, change_detection=change_detection, **PROCESS_NOISE)


class LoopEstimator(Protocol):
    """What the loop reads of its estimator each sample: the state estimate and the parameters."""

    @property
    def x(self) -> np.ndarray: ...

    def params(self) -> CartParams: ...


class EstimatingLoop:
    """Controller callback for :func:`cart.simulate.simulate`: EKF, then controller, then the applied wrench.

    At each sample the EKF (created from the first measurement) predicts over the
    last period under the wrench it was given last (``gamma_in``; with
    ``gamma_cov``, the covariance density of that wrench's error, see
    :meth:`cart.ekf.CartEKF.step`; ``substeps`` Euler predictions then one
    update when > 1) and fuses the measurement; :meth:`_record` stores the
    estimate; the controller's gamma on the estimate goes through :meth:`_apply`,
    which returns the wrench applied to the cart and sets the EKF's next input.
    Here the input is exact and :meth:`_apply` adds the least-effort lateral force
    at the contact (paper §II.C); ``studies.excitation_study`` overrides both
    hooks (a sensed wrench and its arm allocation).
    """

    def __init__(
        self, controller, guess: CartParams, config: EKFConfig, contact: Callable, n: int, substeps: int = 1
    ) -> None:
        self.controller = controller
        self.guess = guess
        self.config = config
        self.contact = contact
        self.substeps = int(substeps)
        #: the paper's EKF (the online estimator in `OnlineLoop`), created at the first sample
        self.ekf: CartEKF | OnlineLSEstimator | None = None
        self.gamma_in = np.zeros(3)
        self.gamma_cov: np.ndarray | None = None
        self.t_prev = 0.0
        self.k = 0
        self.params_hat = np.empty((n, 4))
        self.nis = np.full(n, np.nan)

    def _filter(self, t: float, q_meas: np.ndarray, qd_meas: np.ndarray) -> LoopEstimator:
        """Create the EKF at the first sample, else predict under ``gamma_in`` and fuse (q_meas, qd_meas)."""
        z = np.concatenate([q_meas, qd_meas])
        ekf = self.ekf
        if ekf is None:
            self.ekf = CartEKF(q_meas, qd_meas, self.guess.phi, self.guess.sigma, self.config)
            return self.ekf
        if not isinstance(ekf, CartEKF):
            raise CartError(f"{type(self).__name__} runs the paper's EKF, got a {type(ekf).__name__}")
        dt = t - self.t_prev
        cov = None if self.gamma_cov is None else self.gamma_cov * dt
        if self.substeps == 1:
            self.nis[self.k] = ekf.step(self.gamma_in, dt, z, gamma_cov=cov)
        else:  # finer Euler prediction (same input held), one update
            h = dt / self.substeps
            for _ in range(self.substeps):
                ekf.predict(self.gamma_in, h, gamma_cov=cov)
            self.nis[self.k] = ekf.update(z)
        return ekf

    def _record(self, params: CartParams) -> None:
        """Store the estimate of sample k."""
        self.params_hat[self.k] = (params.m, params.dx, params.dy, params.I)

    def _apply(self, t: float, x_hat: np.ndarray, gamma: np.ndarray) -> np.ndarray:
        """Return the wrench applied until the next sample (and make it the EKF's next input)."""
        gamma = min_effort_gamma(x_hat[:3], gamma, self.contact(t))
        self.gamma_in = gamma
        return gamma

    def __call__(self, t: float, q_meas: np.ndarray, qd_meas: np.ndarray) -> np.ndarray:
        """Return the applied gamma for the sample at time t."""
        ekf = self._filter(t, q_meas, qd_meas)
        params = ekf.params()
        self._record(params)
        gamma = self.controller.gamma(t, ekf.x[:3], ekf.x[3:6], params)
        applied = self._apply(t, ekf.x, gamma)
        self.t_prev = t
        self.k += 1
        return applied


class OnlineLoop(EstimatingLoop):
    """Table I's closed loop with the online estimator in place of the paper's EKF (same controller, same wrench)."""

    def __init__(self, *args, meas_std: np.ndarray, options: dict | None = None, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.meas_std = meas_std
        self.options = dict(options or {})

    def _filter(self, t: float, q_meas: np.ndarray, qd_meas: np.ndarray) -> OnlineLSEstimator:
        """Create the estimator at the first sample, else update it with the last wrench and this measurement."""
        from cart.online_estimator import OnlineLSEstimator, make_online_estimator

        z = np.concatenate([q_meas, qd_meas])
        est = self.ekf
        if est is None:
            self.ekf = make_online_estimator(z, self.guess, self.meas_std, **self.options)
            return self.ekf
        if not isinstance(est, OnlineLSEstimator):
            raise CartError(f"OnlineLoop runs the online estimator, got a {type(est).__name__}")
        self.nis[self.k] = est.step(self.gamma_in, t - self.t_prev, z)
        return est


def run_test(
    test: Table1Test,
    estimate: bool = True,
    controller: ControllerName = "fl_lqr",
    duration: float = 30.0,
    dt: float = 0.01,
    seed: int = 0,
    trajectory: UnicycleTrajectory | None = None,
    change_detection: bool = False,
    estimator: str = "ekf",
) -> TestRun:
    """Return the time series of one test, with or without parameter estimation.

    ``estimator``: "ekf" (the paper's) or "online" (`cart.online_estimator`, used only when estimating).
    """
    make_loop = lambda ctrl, n: _loop(test, ctrl, n, estimate, estimator, change_detection)  # noqa: E731
    return simulate_test(test, make_loop, controller, duration, dt, seed, trajectory)[0]


def simulate_test(
    test: Table1Test,
    make_loop: Callable[[Any, int], EstimatingLoop],
    controller: ControllerName = "fl_lqr",
    duration: float = 30.0,
    dt: float = 0.01,
    seed: int = 0,
    trajectory: UnicycleTrajectory | None = None,
) -> tuple[TestRun, EstimatingLoop]:
    """Return (the time series, the loop) of one test closed by ``make_loop(controller, n_samples)``."""
    traj = trajectory or (trajectory_1(duration) if test.traj == 1 else trajectory_2(duration))
    ctrl = make_controller(controller, traj)
    truth = true_params(test)
    masses = [truth.m, *(mc for _, mc in test.mass_changes)]
    changes = [
        ParameterChange(tc, truth.with_mass(mc), conserve_momentum=test.momentum_exchange and mc > m_old)
        for (tc, mc), m_old in zip(test.mass_changes, masses)
        if tc < duration
    ]
    loop = make_loop(ctrl, int(round(duration / dt)) + 1)
    rng = np.random.default_rng(seed * 1000 + test.test)
    q0, _, _ = traj.sample(0.0)
    sim = simulate(
        truth,
        loop,
        duration,
        dt,
        q0=q0,
        noise=MeasurementNoise.from_level(test.noise),
        rng=rng,
        changes=changes,
        contact_point=contact_point(test),
        allocate=False,
    )
    run = TestRun(
        t=sim.true.t,
        q=sim.true.q,
        q_desired=traj.poses(sim.true.t),
        params_true=sim.params_t,
        params_hat=loop.params_hat,
        nis=loop.nis,
        gamma=sim.true.gamma,
        events=tuple(e.as_dict() for e in getattr(loop.ekf, "events", ())),
    )
    return run, loop


def _loop(test: Table1Test, ctrl, n: int, estimate: bool, estimator: str, change_detection: bool) -> EstimatingLoop:
    """Return the estimating loop of a run: the paper's EKF, or the online estimator when estimating with it."""
    if estimator not in ("ekf", "online"):
        raise ParameterError(f"estimator must be 'ekf' or 'online', got {estimator!r}")
    if estimate and estimator == "online":
        std = MeasurementNoise.from_level(test.noise).measurement_std()
        return OnlineLoop(ctrl, guess_params(test), ekf_config(test.noise), contact_point(test), n, meas_std=std)
    return EstimatingLoop(
        ctrl, guess_params(test), ekf_config(test.noise, estimate, change_detection), contact_point(test), n
    )


def mass_converged_time(t: np.ndarray, m_hat: np.ndarray, m_true: np.ndarray, tol: float = 1.0) -> float | None:
    """Return the first time after which |m_hat - m_true| < tol holds to the end (None if never)."""
    ok = np.abs(m_hat - m_true) < tol
    if not ok[-1]:
        return None
    bad = np.nonzero(~ok)[0]
    return float(t[0]) if bad.size == 0 else float(t[bad[-1] + 1])


def estimation_error_metrics(run: TestRun, after: float = 5.0) -> dict:
    """Return the time-resolved estimation errors of a run against its (possibly changing) true parameters.

    The push loop's fields (`cart.estimation_metrics.estimation_errors`); Table I's truth may change during
    the run (test 11).
    """
    return estimation_errors(
        run.t, run.params_hat[:, 0], run.params_hat[:, 1:3], run.params_true[:, 0], run.params_true[:, 1:3], after
    )


def _tracking_mm_after(run: TestRun, t0: float) -> tuple[float, float]:
    """Return (RMS, max) of the tracking error |p_d - p| over t >= t0, in mm."""
    err = run.position_error[run.t >= t0]
    return 1e3 * float(np.sqrt(np.mean(err**2))), 1e3 * float(np.max(err))


def online_metrics(run: TestRun) -> dict:
    """Return the online estimator's row of a test: final mass error, estimation errors, detected load changes."""
    return {
        "mass_error_final_kg": float(abs(run.params_hat[-1, 0] - run.params_true[-1, 0])),
        **estimation_error_metrics(run),
        "load_changes": list(run.events),
    }


def table1_result(test: Table1Test, run: TestRun, run0: TestRun, run_online: TestRun | None = None) -> TestResult:
    """Return the Table I metrics of a test from its runs with (``run``) and without (``run0``) estimation.

    ``run_online``: the same test with the online estimator, reported beside the paper's EKF.
    """
    m_true = run.params_true[:, 0]
    com_err = float(np.hypot(*(run.params_hat[-1, 1:3] - run.params_true[-1, 1:3])))
    rms, mx = _tracking_mm_after(run, 5.0)
    rms0, mx0 = _tracking_mm_after(run0, 5.0)
    return TestResult(
        test=test.test,
        mass_error_final_kg=float(abs(run.params_hat[-1, 0] - m_true[-1])),
        mass_converged_s=mass_converged_time(run.t, run.params_hat[:, 0], m_true),
        com_error_final_m=com_err,
        tracking_rms_mm=rms,
        tracking_rms_no_estimation_mm=rms0,
        tracking_max_after_5s_mm=mx,
        tracking_max_after_5s_no_estimation_mm=mx0,
        run=run,
        run_no_estimation=run0,
        estimation=estimation_error_metrics(run),
        online={} if run_online is None else online_metrics(run_online),
    )


def evaluate(
    test: Table1Test,
    controller: ControllerName = "fl_lqr",
    duration: float = 30.0,
    dt: float = 0.01,
    seed: int = 0,
    change_detection: bool = False,
) -> TestResult:
    """Return the Table I metrics of one test (runs it with and without estimation)."""
    run = run_test(test, True, controller, duration, dt, seed, change_detection=change_detection)
    run0 = run_test(test, False, controller, duration, dt, seed)
    return table1_result(test, run, run0)


def default_workers() -> int:
    """Return the CPUs this process may use (the default number of worker processes of :func:`run_table1`)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


@dataclass(frozen=True)
class RunFailure:
    """A run of a test that stopped with an error: which run, and the error's type and message."""

    run: str
    reason: str


@dataclass(frozen=True)
class FailedTest:
    """A test whose run with the paper's EKF, or without estimation, stopped with an error: no metrics."""

    test: int
    reason: str

    def as_json(self) -> dict:
        """Return the JSON object of `cartpush reproduce --json` for this test: its number and why it failed."""
        return {"test": self.test, "failed": self.reason}


def _run_name(estimate: bool, estimator: str) -> str:
    return "no estimation" if not estimate else ("the paper's EKF" if estimator == "ekf" else "online estimator")


def _run_job(job: tuple[Table1Test, bool, ControllerName, float, float, int, bool, str]) -> TestRun | RunFailure:
    """Run one (test, estimate, ..., estimator) job of :func:`run_table1` (a worker process's task).

    A run that stops with a numerical error (a diverging estimate, a singular matrix) is returned as a
    :class:`RunFailure`, so that the other tests are still reported.
    """
    test, estimate, controller, duration, dt, seed, change_detection, estimator = job
    detect = change_detection and estimate and estimator == "ekf"
    try:
        return run_test(test, estimate, controller, duration, dt, seed, change_detection=detect, estimator=estimator)
    except (ArithmeticError, ValueError) as exc:  # CartError and numpy's LinAlgError are ValueErrors
        return RunFailure(_run_name(estimate, estimator), f"{type(exc).__name__}: {exc}")


def _test_result(test: Table1Test, runs: Sequence[TestRun | RunFailure]) -> TestResult | FailedTest:
    """Return a test's result from its runs (EKF, no estimation[, online]); a failed online run is its row's reason."""
    failed = [r for r in runs[:2] if isinstance(r, RunFailure)]
    if failed:
        return FailedTest(test.test, "; ".join(f"{f.run} run failed: {f.reason}" for f in failed))
    run, run0 = runs[0], runs[1]
    assert isinstance(run, TestRun) and isinstance(run0, TestRun)
    online = runs[2] if len(runs) > 2 else None
    if isinstance(online, RunFailure):
        result = table1_result(test, run, run0)
        return replace(result, online={"failed": f"{online.run} run failed: {online.reason}"})
    return table1_result(test, run, run0, online)


def _run_jobs(jobs: Sequence[tuple], workers: int) -> Iterator[tuple[int, TestRun | RunFailure]]:
    """Yield (job index, run) as the runs finish: in this process (workers 1) or on forked worker processes."""
    if workers <= 1 or len(jobs) <= 1:
        for i, job in enumerate(jobs):
            yield i, _run_job(job)
        return
    methods = multiprocessing.get_all_start_methods()
    ctx = multiprocessing.get_context("fork" if "fork" in methods else None)  # fork: no re-import per worker
    for traj in {job[0].traj for job in jobs}:  # build the trajectory grids once, before forking
        (trajectory_1 if traj == 1 else trajectory_2)(jobs[0][3])._grid()
    with ProcessPoolExecutor(max_workers=min(workers, len(jobs)), mp_context=ctx) as pool:
        futures = {pool.submit(_run_job, job): i for i, job in enumerate(jobs)}
        for future in as_completed(futures):
            yield futures[future], future.result()


def run_table1(
    tests: Sequence[Table1Test] = TESTS,
    controller: ControllerName = "fl_lqr",
    duration: float = 30.0,
    dt: float = 0.01,
    seed: int = 0,
    progress: Callable[[int], None] | None = None,
    change_detection: bool = False,
    workers: int | None = None,
    online: bool = True,
) -> list[TestResult | FailedTest]:
    """Return the TestResult of every test, in the order of ``tests``.

    The runs of every test (with and without estimation, and with the online estimator when ``online``) are
    independent jobs, run on ``workers`` processes (None: :func:`default_workers`; 1: in this process); every
    run has its own seeded noise, so the results do not depend on ``workers``. ``progress(test)`` is called
    as each test's runs are done. A test whose EKF or no-estimation run fails is a :class:`FailedTest`; a failed
    online run is reported in the test's ``online`` row (``{"failed": reason}``).
    """
    kinds = [(True, "ekf"), (False, "ekf")] + ([(True, "online")] if online else [])
    jobs = [
        (test, estimate, controller, duration, dt, seed, change_detection, estimator)
        for test in tests
        for estimate, estimator in kinds
    ]
    runs: dict = {}
    per = len(kinds)
    for i, run in _run_jobs(jobs, default_workers() if workers is None else int(workers)):
        runs[i] = run
        first = i - i % per
        if progress is not None and all(first + j in runs for j in range(per)):
            progress(jobs[first][0].test)
    return [_test_result(test, [runs[per * k + j] for j in range(per)]) for k, test in enumerate(tests)]
