"""Benchmark and confusion-matrix study of `cart.diagnose` on logs from the hidden-effect test bed.

Usage:
  .venv/bin/python benchmarks/bench_diagnose.py            # timing of a 60 s, 100 Hz log
  .venv/bin/python benchmarks/bench_diagnose.py --study 20 # + confusion matrix, 20 random cases per class

The study draws random carts (15-60 kg, CoM 0.1-0.5 m forward, +-0.15 m sideways),
random push/pull motions with turns and >= 1 reversal, rates 50-200 Hz with jitter,
position noise 1-4 mm, force noise 2-4 N, velocity columns present or not,
and random effect sizes (cart.hidden.random_case). Never asserts a time.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from cart.diagnose import diagnose
from cart.hidden import HIDDEN_NAMES, random_case, random_cart, simulate_hidden

CLASSES = ("none",) + HIDDEN_NAMES


def timing(repeats: int = 3) -> None:
    """Print the median diagnose time of a 60 s log at 100 Hz."""
    rng = np.random.default_rng(0)
    h = simulate_hidden(random_cart(rng), (), duration=60.0, rate=100.0, jitter=0.1, rng=rng)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        diagnose(h.measured)
        times.append(time.perf_counter() - t0)
    print(f"| case | samples | median time [s] | budget [s] | ratio |\n|---|---|---|---|---|\n"
          f"| 60 s log, 100 Hz | {len(h.measured)} | {np.median(times):.2f} | 30 | {np.median(times) / 30:.3f} |")


def study(n: int, seed0: int = 1000, duration: float = 30.0) -> None:
    """Print the confusion matrix (hidden x first named) and the gap ratios over n cases per class."""
    conf = {c: {d: 0 for d in CLASSES} for c in CLASSES}
    ratios = {c: [] for c in HIDDEN_NAMES}
    for ci, c in enumerate(CLASSES):
        for k in range(n):
            rng = np.random.default_rng(seed0 + 1000 * ci + k)
            h = random_case(None if c == "none" else c, rng, duration=duration)
            r = diagnose(h.measured)
            first = r.names[0] if r.names else "none"
            conf[c][first] += 1
            if c != "none" and first == c:
                ratios[c].append(r.gap_after / max(r.gap_before, 1e-12))
        print(f"{c}: done", file=sys.stderr)
    short = {c: c.replace("_", " ")[:10] for c in CLASSES}
    print("| hidden \\ first named | " + " | ".join(short[c] for c in CLASSES) + " | correct |")
    print("|---" * (len(CLASSES) + 2) + "|")
    for c in CLASSES:
        row = conf[c]
        print(f"| {c} | " + " | ".join(str(row[d]) for d in CLASSES) + f" | {row[c] / n:.0%} |")
    print("\n| effect | median gap_after/gap_before | max | share <= 0.5 |\n|---|---|---|---|")
    for c in HIDDEN_NAMES:
        r = np.array(ratios[c]) if ratios[c] else np.array([np.nan])
        print(f"| {c} | {np.median(r):.2f} | {np.max(r):.2f} | {np.mean(r <= 0.5):.0%} |")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--study", type=int, default=0, help="cases per class for the confusion matrix (0: timing only)")
    ap.add_argument("--seed", type=int, default=1000)
    a = ap.parse_args()
    timing()
    if a.study:
        study(a.study, a.seed)
