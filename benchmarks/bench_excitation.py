"""Benchmark + study: contact-schedule planning time, and the EKF's CoM convergence on Traj. 2 per schedule.

Run: .venv/bin/python benchmarks/bench_excitation.py [--seeds N] [--inputs fused,measured]
                                                     [--plans com_a_path:30,com_a_path:12,com_a:6,min_eig:6]
                                                     [--fixed 0.25,0,0.5]
Reproduces the tables of docs/contacts.md ("Persistence of excitation"); the
default (3 seeds) is the quick `make bench` run. Prints times (never asserts
one) and markdown tables. Schedules: planned by each objective:segments on the
planning model (the EKF's initial guess, 16 kg, CoM (0.3, 0)) with 5 candidate
points on the handle, and fixed at the centre and at both ends of the handle.
"""

from __future__ import annotations

import argparse
import builtins
import json
import time

import numpy as np

from cart.params import CartParams
from cart.trajectories import trajectory_2
import studies.excitation_study as study
import wholebody.contacts.excitation as ex

LETTERS = {0.0: "L", 0.125: "l", 0.25: "C", 0.375: "r", 0.5: "R"}  # handle points s: y = s - 0.25


def plans(noise: ex.WrenchNoise, specs: list[tuple[str, int]], fixed: list[float]) -> tuple[dict, dict, dict]:
    """Return (schedules, planning times [s], score strings) for the planned and fixed contacts."""
    guess = CartParams(*study.STUDY_GUESS)
    samples = ex.sample_push(trajectory_2(), dt=0.05)
    scheds, times = {}, {}
    for obj, segs in specs:
        t0 = time.perf_counter()
        plan = ex.plan_contact_schedule(
            samples, guess.phi, guess.sigma, n_segments=segs, n_candidates=5, noise=noise, objective=obj, sensor_dt=0.01
        )
        label = f"planned {obj}, {segs} x {30 / segs:g} s"
        times[label] = time.perf_counter() - t0
        scheds[label] = plan.schedule
        print(
            f"{label}: {''.join(LETTERS.get(round(float(v), 3), '?') for v in plan.schedule.s)} "
            f"(L: y = -0.25, C: y = 0, R: y = +0.25); effort {plan.effort:.0f} (budget {plan.budget:.0f}); "
            f"best fixed by this score: s = {plan.fixed_s:g}"
        )
    names = {0.25: "fixed centre (y = 0)", 0.0: "fixed end y = -0.25", 0.5: "fixed end y = +0.25"}
    for c in fixed:
        scheds[names.get(c, f"fixed s = {c:g}")] = lambda t, c=c: c
    P0 = ex.default_prior(guess.phi)
    scores = {}
    for label, sc in scheds.items():
        me = ex.schedule_score(samples, sc, guess.phi, noise=noise, sensor_dt=0.01)
        ca = ex.schedule_score(samples, sc, guess.phi, noise=noise, objective="com_a", prior_cov=P0, sensor_dt=0.01)
        scores[label] = f"{me:.3g} / {1000 * np.sqrt(-ca):.2f}"
    return scheds, times, scores


def main(argv=None) -> None:
    """Print the study tables (or, with --json, one JSON object of planning/study times and the table rows)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--inputs", default="fused")
    ap.add_argument("--plans", default="com_a_path:30,com_a_path:12,com_a:6,min_eig:6")
    ap.add_argument("--fixed", default="0.25,0,0.5", help="fixed contacts, handle coordinate s in [0, 0.5] m")
    ap.add_argument("--json", action="store_true", help="print one JSON object instead of the tables")
    args = ap.parse_args(argv)
    report = {}
    _print = builtins.print
    print = (lambda *a, **k: None) if args.json else _print  # noqa: A001 - tables only without --json
    specs = [(p.split(":")[0], int(p.split(":")[1])) for p in args.plans.split(",") if p]
    for mode in args.inputs.split(","):
        model = ex.input_model(mode)
        print(
            f"\n## EKF input: {mode} (input error std {model.noise.force:.3g} N, {model.noise.torque:.3g} N m "
            f"in {{a}}), {args.seeds} seeds"
        )
        scheds, times, scores = plans(model.noise, specs, [float(c) for c in args.fixed.split(",") if c])
        print("planning time [s]: " + ", ".join(f"{k} {v:.2f}" for k, v in times.items()))
        t0 = time.perf_counter()
        rows, _ = study.contact_study(scheds, range(args.seeds), ekf_input=mode)
        print(f"study time: {time.perf_counter() - t0:.0f} s ({len(scheds) * args.seeds} closed-loop runs of 30 s)")
        print("score column: min-eig score / CoM CRLB sqrt(trace) [mm], both on the planning model\n")
        print(study.format_table(rows, scores))
        print()
        print(study.format_paired(rows, rows[0].label))
        report[mode] = {
            "planning_s": times,
            "study_s": time.perf_counter() - t0,
            "scores": scores,
            "rows": [_row(r) for r in rows],
        }
    if args.json:
        _print(json.dumps(report, default=float))


def _row(row) -> dict:
    """A study row as a JSON-able dict (dataclass fields; numpy arrays as lists)."""
    import dataclasses

    if dataclasses.is_dataclass(row):
        return {k: (v.tolist() if hasattr(v, "tolist") else v) for k, v in dataclasses.asdict(row).items()}
    return {"row": str(row)}


if __name__ == "__main__":
    main()
