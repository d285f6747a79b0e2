"""Benchmark: `estimate` of a 60 s, 100 Hz log: whole-log least squares vs the EKF multi-start.

Times, in the same run and interleaved (medians over repeats):
- ``ls``: :func:`cart.identify.identify` plus the EKF innovation check
  (:func:`cart.identify.innovation_check`), which is what `cartpush estimate` runs by default;
- ``ekf``: :func:`cart.ekf.estimate_from_log` with its multi-start (three starts and a
  refinement), `cartpush estimate --method ekf`;
- the whole process `cartpush estimate LOG --json` (start-up included), both methods.

The log comes from the independent test bed (``studies.testbeds.rigid_sim``), 60 s at 100 Hz.
Never asserts a time.

``--lengths 1 5 20``: also :func:`cart.estimate_report.estimate_log` (what `cartpush estimate` runs)
on 200 Hz logs of those many minutes (issue 30: linear in the log's length; 20 minutes within 3 s);
the logs are simulated first (about a minute for 20 minutes of log) and cached in ``--cache DIR``.

Run: .venv/bin/python benchmarks/bench_estimate.py [--repeats N] [--json] [--lengths 1 5 20] [--cache DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from cart.ekf import estimate_from_log  # noqa: E402
from cart.identify import identify, innovation_check  # noqa: E402
from cart.logs import write_log  # noqa: E402
from cart.params import CartParams  # noqa: E402
from studies.testbeds import rigid_sim  # noqa: E402

#: whole-process target of `cartpush estimate LOG --json` on a 60 s, 100 Hz log (issue #18)
TARGET_S = 1.0


def _time(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def _lengths(minutes: list[float], cache: str, repeats: int, as_json: bool) -> int:
    """Time estimate_log on 200 Hz logs of the given lengths (minutes); print a table or JSON."""
    from cart.estimate_report import estimate_log
    from cart.logs import read_log

    os.makedirs(cache, exist_ok=True)
    rows = []
    for mins in minutes:
        path = os.path.join(cache, f"long_{mins:g}min.csv.gz")
        if not os.path.exists(path):
            rigid_sim.write_case(rigid_sim.random_case(11, duration=60.0 * mins, rate_hz=200.0, m=40.0), path)
        log = read_log(path)
        times = [_time(lambda: estimate_log(log)) for _ in range(repeats)]
        rows.append({"minutes": mins, "samples": len(log), "median_s": statistics.median(times)})
    if as_json:
        print(json.dumps({"estimate_log_by_length": rows}))
        return 0
    print("estimate_log on 200 Hz logs (independent simulator), medians of", repeats)
    for r in rows:
        print(f"  {r['minutes']:5g} min  {r['samples']:8d} samples  {r['median_s']:7.2f} s")
    return 0


def main(argv=None) -> int:
    """Run the benchmark; print a table (or one JSON object)."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--lengths", type=float, nargs="*", default=[], metavar="MIN")
    ap.add_argument("--cache", default=os.path.join(tempfile.gettempdir(), "cartpush_bench_estimate"))
    args = ap.parse_args(argv)
    if args.lengths:
        return _lengths(args.lengths, args.cache, args.repeats, args.json)
    case = rigid_sim.random_case(11, duration=60.0, rate_hz=100.0, jitter=0.0, vel_std=None)
    log, truth = rigid_sim.simulate(case)
    guess = CartParams(20.0, 0.0, 0.0, 2.0, 1.0)

    def ls():
        res = identify(log)
        innovation_check(log, res.params)

    def ekf():
        estimate_from_log(log, guess, estimate_sigma=True)

    t_ls, t_ekf = [], []
    for _ in range(args.repeats):
        t_ls.append(_time(ls))
        t_ekf.append(_time(ekf))
    exe = os.path.join(os.path.dirname(sys.executable), "cartpush")
    proc = {}
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "log.csv")
        write_log(path, log)
        for method in ("ls", "ekf"):
            runs = [
                _time(
                    lambda: subprocess.run(
                        [exe, "estimate", path, "--method", method, "--json"], check=True, capture_output=True
                    )
                )
                for _ in range(3)
            ]
            proc[method] = statistics.median(runs)
    out = {
        "log": {"duration_s": 60.0, "rate_hz": 100.0, "samples": len(log)},
        "ls_median_s": statistics.median(t_ls),
        "ekf_multistart_median_s": statistics.median(t_ekf),
        "ratio_ekf_over_ls": statistics.median(t_ekf) / statistics.median(t_ls),
        "process_ls_median_s": proc["ls"],
        "process_ekf_median_s": proc["ekf"],
        "process_target_s": TARGET_S,
        "ratio_process_ls_over_target": proc["ls"] / TARGET_S,
        "mass_true": truth["m"],
        "mass_ls": identify(log).params.m,
    }
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"estimate of a 60 s, 100 Hz log ({len(log)} samples), medians of {args.repeats}")
    print(f"  least squares + innovation check : {out['ls_median_s'] * 1e3:8.1f} ms")
    print(
        f"  EKF multi-start (4 runs)         : {out['ekf_multistart_median_s'] * 1e3:8.1f} ms"
        f"   ({out['ratio_ekf_over_ls']:.1f}x the least squares)"
    )
    print(
        f"  whole process, --method ls       : {proc['ls']:8.2f} s   (target {TARGET_S:.0f} s: "
        f"{proc['ls'] / TARGET_S:.2f}x)"
    )
    print(f"  whole process, --method ekf      : {proc['ekf']:8.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
