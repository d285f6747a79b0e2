"""Benchmark: combined Jacobian, one QP IK step, and placo's solver step on the same robot (median us).

Run: .venv/bin/python benchmarks/bench_wholebody.py [--json]
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np
import pinocchio as pin

import robots
from wholebody.motion.control import ControllerConfig, ResolvedRateController
from studies.wmra_experiments import initial_state
from wholebody.motion.kinematics import wholebody_for
from studies.placo_compare import PlacoTracker
from studies import wmra_closed_form as cf


def median_us(fn, repeat: int = 2000) -> float:
    """Return the median wall time of fn() in microseconds."""
    for _ in range(50):
        fn()
    times = np.empty(repeat)
    for i in range(repeat):
        t0 = time.perf_counter()
        fn()
        times[i] = time.perf_counter() - t0
    return float(np.median(times) * 1e6)


def main(argv=None) -> None:
    """Print the table (or, with --json, one JSON object of the medians and ratios)."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    args = ap.parse_args(argv)
    rows = []
    for name in ("wmra", "ridgeback_iiwa"):
        wb = wholebody_for(robots.load(name))
        x = initial_state(wb)
        T0 = wb.ee_placement(x)
        jac = median_us(lambda: wb.combined_jacobian(x))
        ctrl = ResolvedRateController(wb, ControllerConfig())
        T_des = pin.SE3(T0.rotation, T0.translation + [0.001, 0.0005, 0.0])
        v = np.r_[0.09, 0.05, 0, 0, 0, 0]
        qp = median_us(lambda: ctrl.step(x, T_des, v, 0.01), 1000)
        tr = PlacoTracker(wb, x, 0.01)
        Tp = tr.ee()
        k = [0]

        def placo_step():
            k[0] += 1
            tr.step(pin.SE3(Tp.rotation, Tp.translation + [0.0009 * k[0], 0.0, 0.0]))

        pl = median_us(placo_step, 1000)
        rows.append((name, jac, qp, pl))
        if name == "wmra":
            from robots.wmra import WMRA_D, WMRA_MOUNT, WMRA_TRACK, WMRA_WHEEL_RADIUS

            cfj = median_us(lambda: cf.combined_jacobian(x[:3], x[3:], WMRA_D, WMRA_TRACK, WMRA_MOUNT,
                                                         WMRA_WHEEL_RADIUS))
    if args.json:
        print(json.dumps({"robots": {name: {"jacobian_us": jac, "qp_step_us": qp, "placo_step_us": pl,
                                            "ratio_qp_vs_placo": qp / pl} for name, jac, qp, pl in rows},
                          "wmra_closed_form_jacobian_us": cfj}))
        return
    print(f"{'robot':<16}{'jacobian [us]':>15}{'QP IK step [us]':>17}{'placo step [us]':>17}{'ours/placo':>12}")
    for name, jac, qp, pl in rows:
        print(f"{name:<16}{jac:>15.1f}{qp:>17.1f}{pl:>17.1f}{qp / pl:>12.1f}")
    print(f"(WMRA closed-form numpy Jacobian, paper eq. 19-20: {cfj:.1f} us)")


if __name__ == "__main__":
    main()
