"""Benchmark: `estimate` of a 60 s, 100 Hz log: whole-log least squares vs the EKF multi-start.

Times, in the same run and interleaved (medians over repeats):
- ``ls``: :func:`cart.identify.identify` plus the EKF innovation check
  (:func:`cart.identify.innovation_check`), which is what `cartpush estimate` runs by default;
- ``ekf``: :func:`cart.ekf.estimate_from_log` with its multi-start (three starts and a
  refinement), `cartpush estimate --method ekf`;
- the whole process `cartpush estimate LOG --json` (start-up included), both methods.

The log comes from the independent test bed (``studies.testbeds.rigid_sim``), 60 s at 100 Hz.
Never asserts a time.

``--lengths 1 5 20``: instead, on 200 Hz logs of those many minutes (issue 30: linear in the log's
length; 20 minutes within 3 s), the CPU and wall time of :func:`cart.estimate_report.estimate_log` in
process (what `cartpush estimate` runs; medians of ``--repeats``, after one untimed call that pays the lazy
imports) and of the whole process ``cartpush estimate LOG --json`` (reading the log and start-up included:
CPU = user + system and wall, medians of ``--repeats`` runs, and the peak resident memory), each process run
followed by the reference, a pure-Python loop of 10^7 additions (its median CPU time: the machine's speed). The logs are simulated first (about a
minute for 20 minutes of log) and cached in ``--cache DIR``. ``--tiled``: also the 20-minute log of
``benchmarks/malformed_suite.py`` (a 40 s, 100 Hz push repeated on a 200 Hz clock, jumps every 40 s).
OpenBLAS runs on one thread (``OPENBLAS_NUM_THREADS=1`` unless set), as `cartpush estimate` runs it.

Run: .venv/bin/python benchmarks/bench_estimate.py [--repeats N] [--json] [--lengths 1 5 20 [--tiled]] [--cache DIR]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # read when numpy loads: as `cartpush estimate` sets it

import numpy as np  # noqa: E402

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


def _reference_loop() -> float:
    """Return the CPU seconds of a pure-Python loop of 10^7 additions: the machine's speed beside the timings."""
    c0 = time.process_time()
    total = 0
    for i in range(10_000_000):
        total += i
    return time.process_time() - c0


def _process_once(path: str) -> tuple[float, float, float, float | None]:
    """Return (CPU = user + system s, wall s, peak resident MB, mass) of one `cartpush estimate PATH --json`."""
    exe = os.path.join(os.path.dirname(sys.executable), "cartpush")
    t0 = time.perf_counter()
    proc = subprocess.Popen([exe, "estimate", path, "--json"], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    out = proc.stdout.read() if proc.stdout else b""
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    mass = json.loads(out)["mass"] if status == 0 else None
    return usage.ru_utime + usage.ru_stime, wall, usage.ru_maxrss / 1024.0, mass


def _process(path: str, runs: int = 1) -> dict:
    """Return the whole process `cartpush estimate PATH --json` over ``runs`` runs, each followed by the reference
    loop (:func:`_reference_loop`): CPU (user + system) and wall medians and every run, peak resident MB (the
    largest), the mass, and the reference loop's median CPU seconds."""
    cpu, wall, peak, ref, mass = [], [], [], [], None
    for _ in range(max(runs, 1)):
        c, w, mb, mass = _process_once(path)
        cpu.append(c)
        wall.append(w)
        peak.append(mb)
        ref.append(_reference_loop())
    return {
        "process_cpu_s": statistics.median(cpu),
        "process_wall_s": statistics.median(wall),
        "process_cpu_runs": cpu,
        "process_wall_runs": wall,
        "process_peak_mb": max(peak),
        "reference_loop_s": statistics.median(ref),
        "mass": mass,
    }


def _tiled_log(cache: str) -> str:
    """Return the path of the malformed suite's 20-minute tiled log (written into ``cache`` once)."""
    from benchmarks.malformed_suite import _recorder_base
    from cart.logs import CartLog

    path = os.path.join(cache, "tiled_20min.csv.gz")
    if not os.path.exists(path):
        base = _recorder_base().measured
        tl = np.arange(0.0, 1200.0, 0.005)
        reps = int(math.ceil(len(tl) / len(base.t)))
        tiled = CartLog(t=tl, q=np.tile(base.q, (reps, 1))[: len(tl)], gamma=np.tile(base.gamma, (reps, 1))[: len(tl)])
        write_log(path, tiled)
    return path


def _lengths(minutes: list[float], cache: str, repeats: int, tiled: bool, seed: int = 11) -> list[dict]:
    """Return one row per log: samples, estimate_log CPU / wall medians in process, the whole process."""
    from cart.estimate_report import estimate_log
    from cart.logs import read_log

    os.makedirs(cache, exist_ok=True)
    paths = []
    for mins in minutes:
        path = os.path.join(cache, f"long_{mins:g}min.csv.gz" if seed == 11 else f"long_{mins:g}min_s{seed}.csv.gz")
        if not os.path.exists(path):
            rigid_sim.write_case(rigid_sim.random_case(seed, duration=60.0 * mins, rate_hz=200.0, m=40.0), path)
        paths.append((f"{mins:g} min", path))
    if tiled:
        paths.append(("tiled 20 min", _tiled_log(cache)))
    rows = []
    for name, path in paths:
        log = read_log(path)
        estimate_log(log)  # lazy imports out of the timed runs
        cpu, wall = [], []
        for _ in range(repeats):
            c0, w0 = time.process_time(), time.perf_counter()
            estimate_log(log)
            cpu.append(time.process_time() - c0)
            wall.append(time.perf_counter() - w0)
        row = {"log": name, "samples": len(log), "cpu_s": statistics.median(cpu), "wall_s": statistics.median(wall)}
        rows.append({**row, **_process(path, repeats)})
    return rows


def _print_lengths(rows: list[dict], repeats: int) -> None:
    """Print the table of :func:`_lengths`."""
    print(
        f"estimate_log in process and `cartpush estimate LOG --json` (medians of {repeats}; each process run "
        f"followed by a pure-Python loop of 10^7 additions, the reference); load {os.getloadavg()[0]:.1f}"
    )
    print("  log            samples   CPU s  wall s | process CPU s  wall s  peak MB  mass kg | reference s")
    for r in rows:
        mass = r["mass"] if r["mass"] is None else round(r["mass"], 3)
        print(
            f"  {r['log']:13s} {r['samples']:8d} {r['cpu_s']:7.2f} {r['wall_s']:7.2f} | {r['process_cpu_s']:13.2f} "
            f"{r['process_wall_s']:7.2f} {r['process_peak_mb']:8.0f}  {mass} | {r['reference_loop_s']:11.2f}"
        )


def main(argv=None) -> int:
    """Run the benchmark; print a table (or one JSON object)."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--lengths", type=float, nargs="*", default=[], metavar="MIN")
    ap.add_argument("--seed", type=int, default=11, help="with --lengths: the logs' rigid_sim seed")
    ap.add_argument("--tiled", action="store_true", help="with --lengths: also the malformed suite's 20-minute log")
    ap.add_argument("--cache", default=os.path.join(tempfile.gettempdir(), "cartpush_bench_estimate"))
    args = ap.parse_args(argv)
    if args.lengths:
        rows = _lengths(args.lengths, args.cache, args.repeats, args.tiled, args.seed)
        if args.json:
            print(json.dumps({"estimate_by_length": rows, "load": os.getloadavg()[0]}))
        else:
            _print_lengths(rows, args.repeats)
        return 0
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
