"""Benchmark: start-up time of the command line (`cartpush --help`, `cartpush estimate --help`).

Each command runs as a fresh subprocess (the console script next to this Python, or
`python -c 'from cartpush.cli import main; main()'` when there is none): one warm-up run
(fills the OS file cache; printed as `first`), then N timed runs (default 5) whose median,
min and max wall times are printed. The target in issue #16 is under 0.5 s for `--help` and
the cart-only commands; this script reports, it never asserts a time.

Run: .venv/bin/python benchmarks/bench_startup.py [--runs 5] [--json] [--command "diagnose --help" ...]
"""

from __future__ import annotations

import argparse
import json
import shlex
import statistics
import subprocess
import sys
import time
from pathlib import Path

DEFAULT_COMMANDS = ("--help", "estimate --help")
TARGET_S = 0.5


def cartpush_argv() -> list[str]:
    """Return the argv prefix that starts `cartpush` with this interpreter's environment."""
    script = Path(sys.executable).with_name("cartpush")
    if script.is_file():
        return [str(script)]
    return [sys.executable, "-c", "import sys; from cartpush.cli import main; sys.exit(main())"]


def time_once(argv: list[str]) -> float:
    """Return the wall time (s) of one run; raise if the command fails."""
    t0 = time.perf_counter()
    proc = subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    elapsed = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} exited {proc.returncode}: {proc.stderr.strip()[-500:]}")
    return elapsed


def measure(args: str, runs: int) -> dict:
    """Return the start-up statistics of `cartpush ARGS` over `runs` timed runs after one warm-up."""
    argv = cartpush_argv() + shlex.split(args)
    first = time_once(argv)
    times = [time_once(argv) for _ in range(runs)]
    return {
        "command": f"cartpush {args}",
        "runs": runs,
        "first_s": first,
        "median_s": statistics.median(times),
        "min_s": min(times),
        "max_s": max(times),
        "under_target": statistics.median(times) < TARGET_S,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="timed runs per command (default 5)")
    parser.add_argument(
        "--command",
        action="append",
        default=None,
        metavar="ARGS",
        help="cartpush arguments to time (repeatable; default: '--help' and 'estimate --help')",
    )
    parser.add_argument("--json", action="store_true", help="print the results as JSON only")
    a = parser.parse_args()
    rows = [measure(c, a.runs) for c in (a.command or DEFAULT_COMMANDS)]
    if a.json:
        print(json.dumps({"target_s": TARGET_S, "results": rows}, indent=1))
        return 0
    print(f"cartpush start-up: wall time of a fresh process, {a.runs} runs after one warm-up (target < {TARGET_S} s)")
    print(f"{'command':<32} {'first':>8} {'median':>8} {'min':>8} {'max':>8}  < {TARGET_S} s")
    for r in rows:
        print(
            f"{r['command']:<32} {r['first_s']:8.3f} {r['median_s']:8.3f} {r['min_s']:8.3f} {r['max_s']:8.3f}  "
            f"{'yes' if r['under_target'] else 'no'}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
