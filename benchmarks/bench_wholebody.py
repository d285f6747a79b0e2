"""Benchmark: combined Jacobian, one QP IK step, and placo's solver step on the same robot (median us).

The QP step is `ResolvedRateController.step` with the default `ControllerConfig` (daqp called directly), and
with ProxQP called directly, warm-started (`solver="proxqp"`) and cold (`warm_start=False`, which reproduces a
fresh solve). Each is measured at a fixed state and target ("static": the QP repeats) and in closed loop
("tracking": the state integrated after each step, the target moving 0.9 mm per step along x). "cycle" is the
default tracking step plus `WholeBody.integrate`, the same work as placo's timed step. The tracking runs and
placo's run advance in turn, 100 steps at a time, so that a slow spell of the machine falls on all of them.
Last, the first step of a fresh process is timed with an empty numba cache (the compiled kernels of
`wholebody.motion.kernels` compile) and with the cache that run wrote.

placo's step (`PlacoTracker.step_to`) tracks the same moving target: the assignment of the target matrix,
`solve(True)` (solve and integrate) and `update_kinematics()` (FK) are timed. On both sides the target is
built before the clock starts. All in one run.

Run: .venv/bin/python benchmarks/bench_wholebody.py [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator

import numpy as np
import pinocchio as pin

import robots
from studies import wmra_closed_form as cf
from studies.placo_compare import PlacoTracker
from wholebody.motion.experiments import initial_state
from wholebody.motion.control import ControllerConfig, ResolvedRateController
from wholebody.motion.kinematics import WholeBody, wholebody_for

DT = 0.01
STEP = 0.0009  # target displacement per step (m), as placo's


def median_us(fn, repeat: int = 2000, warmup: int = 50) -> float:
    """Return the median wall time of fn() in microseconds."""
    for _ in range(warmup):
        fn()
    times = np.empty(repeat)
    for i in range(repeat):
        t0 = time.perf_counter()
        fn()
        times[i] = time.perf_counter() - t0
    return float(np.median(times) * 1e6)


#: the controller configurations timed: name -> config
CONFIGS = {
    "": ControllerConfig(),
    "proxqp_": ControllerConfig(solver="proxqp"),
    "proxqp_cold_": ControllerConfig(solver="proxqp", warm_start=False),
}


def static_step_us(wb: WholeBody, x: np.ndarray, config: ControllerConfig) -> float:
    """Median time of `step` at a fixed state and target."""
    ctrl = ResolvedRateController(wb, config)
    T0 = wb.ee_placement(x)
    T_des = pin.SE3(T0.rotation, T0.translation + [0.001, 0.0005, 0.0])
    v = np.r_[0.09, 0.05, 0, 0, 0, 0]
    return median_us(lambda: ctrl.step(x, T_des, v, DT), 1000)


def our_tracking(
    wb: WholeBody, x0: np.ndarray, config: ControllerConfig, with_integrate: bool = False
) -> Iterator[float]:
    """Yield the wall time (s) of each closed-loop `step` (and `integrate` if `with_integrate`) along a line."""
    ctrl = ResolvedRateController(wb, config)
    T0 = wb.ee_placement(x0)
    v = np.r_[STEP / DT, 0, 0, 0, 0, 0]
    x, k = x0.copy(), 0
    while True:
        k += 1
        T_des = pin.SE3(T0.rotation, T0.translation + [STEP * k, 0.0, 0.0])
        t0 = time.perf_counter()
        u = ctrl.step(x, T_des, v, DT).u
        t_step = time.perf_counter()
        x = wb.integrate(x, u, DT)
        yield (time.perf_counter() if with_integrate else t_step) - t0


def placo_tracking(wb: WholeBody, x0: np.ndarray) -> Iterator[float]:
    """Yield the wall time (s) of each of placo's closed-loop steps towards the moving target (assignment,
    solve(True), FK)."""
    tr = PlacoTracker(wb, x0, DT)
    Tp, k = tr.ee(), 0
    while True:
        k += 1
        yield tr.step_to(pin.SE3(Tp.rotation, Tp.translation + [STEP * k, 0.0, 0.0]).homogeneous)


def interleaved_medians_us(
    runs: dict[str, Iterator[float]], steps: int = 1000, chunk: int = 100, warmup: int = 50
) -> dict[str, float]:
    """Return each run's median step time (us) over `steps` steps, the runs advanced in turn `chunk` steps at a
    time, so that a slow spell of the machine falls on all of them alike."""
    times: dict[str, list[float]] = {name: [] for name in runs}
    for run in runs.values():
        for _ in range(warmup):
            next(run)
    for _ in range(steps // chunk):
        for name, run in runs.items():
            times[name].extend(next(run) for _ in range(chunk))
    return {name: float(np.median(t) * 1e6) for name, t in times.items()}


def measure(name: str) -> dict[str, float]:
    """Return the medians (us) and ratios to placo for one robot."""
    wb = wholebody_for(robots.load(name))
    x = initial_state(wb)
    r = {"jacobian_us": median_us(lambda: wb.combined_jacobian(x))}
    for prefix, config in CONFIGS.items():
        r[prefix + "step_us"] = static_step_us(wb, x, config)
    runs = {prefix + "tracking_step_us": our_tracking(wb, x, config) for prefix, config in CONFIGS.items()}
    runs["tracking_cycle_us"] = our_tracking(wb, x, ControllerConfig(), with_integrate=True)
    runs["placo_step_us"] = placo_tracking(wb, x)
    r.update(interleaved_medians_us(runs))
    for key in [k for k in r if k not in ("jacobian_us", "placo_step_us")]:
        r["ratio_" + key[:-3] + "_vs_placo"] = r[key] / r["placo_step_us"]
    return r


_FIRST_STEP = """
import time
import robots
from wholebody.motion.experiments import initial_state
from wholebody.motion.control import ResolvedRateController
from wholebody.motion.kinematics import wholebody_for
wb = wholebody_for(robots.load("wmra"))
x = initial_state(wb)
ctrl = ResolvedRateController(wb)
t0 = time.perf_counter()
T = wb.ee_placement(x)
wb.integrate(x, ctrl.step(x, T, None, 0.01).u, 0.01)
print(time.perf_counter() - t0)
"""


def first_step_s() -> dict[str, float]:
    """Return the wall time (s) of a fresh process's first `ee_placement`, step and integrate: with an empty numba cache (the kernels
    compile) and then with the cache that run wrote (the kernels load), both in a temporary NUMBA_CACHE_DIR."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        run = [sys.executable, "-c", _FIRST_STEP]
        compiled = float(subprocess.run(run, env=env, capture_output=True, text=True, check=True).stdout)
        loaded = float(subprocess.run(run, env=env, capture_output=True, text=True, check=True).stdout)
    return {"first_step_empty_cache_s": compiled, "first_step_cached_s": loaded}


def main(argv=None) -> None:
    """Print the table (or, with --json, one JSON object of the medians and ratios)."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    args = ap.parse_args(argv)
    rows = {name: measure(name) for name in ("wmra", "ridgeback_iiwa")}
    from robots.wmra import WMRA_D, WMRA_MOUNT, WMRA_TRACK, WMRA_WHEEL_RADIUS

    x = initial_state(wholebody_for(robots.load("wmra")))
    cfj = median_us(lambda: cf.combined_jacobian(x[:3], x[3:], WMRA_D, WMRA_TRACK, WMRA_MOUNT, WMRA_WHEEL_RADIUS))
    first = first_step_s()
    if args.json:
        print(json.dumps({"robots": rows, "wmra_closed_form_jacobian_us": cfj, **first}))
        return
    cols = ("jacobian_us", "step_us", "tracking_step_us", "tracking_cycle_us")
    cols += ("proxqp_step_us", "proxqp_tracking_step_us", "proxqp_cold_tracking_step_us", "placo_step_us")
    heads = ("jacobian", "step", "tracking", "cycle", "proxqp step", "proxqp track", "proxqp cold tr", "placo step")
    print("median us; ratios = ours / placo (same run); default solver daqp")
    print(
        f"{'robot':<16}"
        + "".join(f"{h:>15}" for h in heads)
        + f"{'step/placo':>12}{'track/placo':>13}{'cycle/placo':>13}"
    )
    for name, r in rows.items():
        print(
            f"{name:<16}"
            + "".join(f"{r[c]:>15.1f}" for c in cols)
            + f"{r['ratio_step_vs_placo']:>12.2f}{r['ratio_tracking_step_vs_placo']:>13.2f}"
            + f"{r['ratio_tracking_cycle_vs_placo']:>13.2f}"
        )
    print(f"(WMRA closed-form numpy Jacobian, paper eq. 19-20: {cfj:.1f} us)")
    print(
        f"first step of a fresh process: {first['first_step_empty_cache_s']:.2f} s with an empty numba cache "
        f"(kernels compile), {first['first_step_cached_s']:.2f} s with the cache"
    )


if __name__ == "__main__":
    main()
