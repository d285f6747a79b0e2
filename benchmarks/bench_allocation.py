"""Benchmark: wrench allocation solve time against the raw ProxQP call on the same QP, and contact-point search.

Run: .venv/bin/python benchmarks/bench_allocation.py [--json] [--repeat N]
Prints medians (per solve, over a control-loop stream of 200 wrenches where a grasp limit binds, repeated);
never asserts a time. Rows:

* "allocator": `WrenchAllocator.solve` as a control loop calls it (ProxQP's dense API called directly and
  warm-started; the closed-form and last-active-set shortcuts, exact when their KKT conditions certify);
* "allocator, QP forced": the same with ``fast_path=False`` (every call solves the QP, then polishes);
* "raw ProxQP": the peer, ``qp.update(b=...); qp.solve()`` on a `proxsuite.proxqp.dense.QP` holding the same
  matrices, settings and warm start, in the same run;
* "qpsolvers <backend>": the QP forced through `qpsolvers` (``direct=False``), cold each call.

Contact points: `optimal_contact_points` (grid 1 cm + local refinement) against the brute force it is proven
equal to on the grid (one allocation QP per grid candidate, as `tests/wholebody/contacts/test_placement_sweep.py` checks).
"""

from __future__ import annotations

import argparse
import builtins
import json
import time
import warnings

import numpy as np
import proxsuite
import qpsolvers

from wholebody.contacts.allocation import PROXQP_EPS_ABS, WrenchAllocator
from wholebody.contacts.handle import HandleSegment
from wholebody.contacts.placement import _grid, optimal_contact_points

warnings.filterwarnings("ignore")


def per_call_us(fn, items, repeat: int) -> float:
    """Return the median wall time (us) of fn(item) over items, repeated."""
    for it in items[:5]:
        fn(it)
    times = []
    for _ in range(repeat):
        for it in items:
            t0 = time.perf_counter()
            fn(it)
            times.append(time.perf_counter() - t0)
    return float(np.median(times) * 1e6)


def raw_proxqp(alloc: WrenchAllocator, b0: np.ndarray):
    """Return a warm-started ProxQP dense QP on the allocator's matrices (the peer of `WrenchAllocator.solve`)."""
    nx = alloc.P.shape[0]
    qp = proxsuite.proxqp.dense.QP(nx, len(alloc.rows), len(alloc.hin))
    qp.settings.eps_abs, qp.settings.eps_rel, qp.settings.verbose = PROXQP_EPS_ABS, 0.0, False
    qp.init(alloc.P, np.zeros(nx), alloc.A, b0, alloc.Gin, np.full(len(alloc.hin), -np.inf), alloc.hin)
    qp.solve()
    qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
    return qp


def stream(center: list[float], n: int = 200) -> list[np.ndarray]:
    """Return a smooth stream of cart wrenches around center (a control loop's requests)."""
    t = np.linspace(0.0, 2.0 * np.pi, n)
    return [
        np.array([center[0] + 0.15 * center[0] * np.sin(u), center[1], center[2] + 0.15 * center[2] * np.cos(u)])
        for u in t
    ]


def allocation_rows(name: str, pts, hard: list[float], easy: list[float], repeat: int) -> dict:
    """Return the per-solve medians (us) of one case: allocator, forced QP, raw ProxQP, qpsolvers backends."""
    wrenches = stream(hard)
    out = {}
    alloc = WrenchAllocator(pts, only_motion_directions=True)
    n_bind = sum(alloc.solve(g).solver != "closed-form" for g in wrenches)
    assert n_bind == len(wrenches), "every wrench of the stream must hit a limit"
    out["allocator"] = per_call_us(alloc.solve, wrenches, repeat)
    forced = WrenchAllocator(pts, only_motion_directions=True, fast_path=False)
    out["allocator, QP forced"] = per_call_us(forced.solve, wrenches, repeat)
    qp = raw_proxqp(forced, wrenches[0][forced.rows])
    rows = forced.rows

    def raw(g: np.ndarray) -> None:
        qp.update(b=g[rows])
        qp.solve()

    out["raw ProxQP"] = per_call_us(raw, wrenches, repeat)
    for solver in (s for s in ("proxqp", "daqp", "osqp") if s in qpsolvers.available_solvers):
        a = WrenchAllocator(pts, only_motion_directions=True, fast_path=False, solver=solver, direct=False)
        out[f"qpsolvers {solver}"] = per_call_us(a.solve, wrenches, max(1, repeat // 3))
    fast = WrenchAllocator(pts, only_motion_directions=True)
    assert fast.solve(easy).solver == "closed-form"
    out["closed-form (no limit binds)"] = per_call_us(fast.solve, [np.asarray(easy)] * 50, repeat)
    out["build"] = per_call_us(lambda _: WrenchAllocator(pts), [None] * 20, max(1, repeat // 2))
    out["ratio allocator / raw ProxQP"] = out["allocator"] / out["raw ProxQP"]
    out["ratio QP forced / raw ProxQP"] = out["allocator, QP forced"] / out["raw ProxQP"]
    return out


def brute_force_ms(gamma, h: HandleSegment, n_arms: int) -> float:
    """Return the time (ms) of one QP allocation per grid candidate (the grid `optimal_contact_points` searches)."""
    cands, _ = _grid(h.length, n_arms, 0.2 if n_arms > 1 else 0.0, 0.01)
    alloc = WrenchAllocator([h.point(0.0)] * n_arms)
    t0 = time.perf_counter()
    for c in cands:
        alloc.set_points([h.point(float(v)) for v in c])
        alloc.solve(gamma, raise_on_infeasible=False)
    return (time.perf_counter() - t0) * 1e3


def main(argv=None) -> None:
    """Print the tables (or, with --json, one JSON object of the medians and ratios)."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true", help="print one JSON object instead of the tables")
    ap.add_argument("--repeat", type=int, default=5, help="passes over the 200-wrench stream (default 5)")
    args = ap.parse_args(argv)
    report = {"allocation_us": {}, "contact_points_ms": {}}
    _print = builtins.print
    print = (lambda *a, **k: None) if args.json else _print  # noqa: A001 - tables only without --json
    h = HandleSegment.default()
    cases = {
        "1 arm": ([h.point(0.35)], [30.0, 0.0, 3.0], [30.0, 0.0, 0.0]),
        "2 arms": ([h.point(0.05), h.point(0.45)], [60.0, 0.0, 14.0], [60.0, 0.0, 2.0]),
    }
    print("allocation, median per solve [us] over a 200-wrench stream where a limit binds")
    for name, (pts, hard, easy) in cases.items():
        rows = allocation_rows(name, pts, hard, easy, args.repeat)
        report["allocation_us"][name] = rows
        for label, v in rows.items():
            print(f"  {name:<7} {label:<32} {v:>9.2f}")
    print()
    print("contact-point optimization (grid 1 cm + local refinement), median [ms]")
    for n_arms, gamma in ((1, [40.0, 0.0, -2.0]), (2, [60.0, 5.0, 3.0])):
        times = []
        for _ in range(max(3, args.repeat)):
            t0 = time.perf_counter()
            plan = optimal_contact_points(gamma, h, n_arms=n_arms)
            times.append((time.perf_counter() - t0) * 1e3)
        t = float(np.median(times))
        brute = float(np.median([brute_force_ms(gamma, h, n_arms) for _ in range(3)]))
        print(
            f"  {n_arms} arm(s): {t:8.2f} ms ({plan.evaluations} allocations); brute force over the grid "
            f"{brute:8.2f} ms; ratio {t / brute:.3f}"
        )
        report["contact_points_ms"][f"{n_arms}_arm"] = {
            "median_ms": t,
            "allocations": plan.evaluations,
            "brute_force_grid_ms": brute,
            "ratio_vs_brute": t / brute,
        }
    if args.json:
        _print(json.dumps(report))


if __name__ == "__main__":
    main()
