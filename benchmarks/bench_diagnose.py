"""Benchmark and confusion-matrix study of `cart.diagnose` on logs from the hidden-effect test bed.

Usage:
  .venv/bin/python benchmarks/bench_diagnose.py                 # timing of 60 s, 100 Hz logs (in process and
                                                                # the whole `cartpush diagnose LOG --json` process)
  .venv/bin/python benchmarks/bench_diagnose.py --json          # the same figures as one JSON object
  .venv/bin/python benchmarks/bench_diagnose.py --study 20      # + confusion matrix, 20 random cases per class
  .venv/bin/python benchmarks/bench_diagnose.py --robust 4      # + robustness conditions, 4 cases per class each
  .venv/bin/python benchmarks/bench_diagnose.py --no-timing --scale 1,5,20   # long 200 Hz logs: wall time and
                                                                # peak RSS of `diagnose` per length (subprocesses)
  options: --seed S (first seed), --no-timing, --repeats N, --json FILE (all per-case results),
           --classes c1,c2 (only these classes; seeds as in the full study), --caster-form profile|swivel

The study draws random carts (15-60 kg, CoM 0.1-0.5 m forward, +-0.15 m sideways),
random push/pull motions with turns and >= 1 reversal, rates 50-200 Hz with jitter,
position noise 1-4 mm, force noise 2-4 N, velocity columns present or not,
and random effect sizes (studies.testbeds.hidden_effects.random_case); caster_swivel cases are half
the resistance-profile form, half swivelling casters (studies.testbeds.hidden_effects.SwivelCasters).
The robustness conditions override one thing each (rate, velocity columns, noise,
effect size). Case k of class c uses seed S + 1000 c + k, so every condition
replays the same carts and motions. Never asserts a time.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from cart.diagnose import diagnose
from cart.logs import write_log
from studies.testbeds.hidden_effects import HIDDEN_NAMES, random_case, random_cart, random_effect, simulate_hidden

CLASSES = ("none",) + HIDDEN_NAMES
#: whole-process target of `cartpush diagnose` on a 60 s, 100 Hz log (issue #18)
TARGET_S = 8.0

#: robustness conditions: name -> (random_case overrides, effect scale)
CONDITIONS: dict[str, tuple] = {
    "50 Hz, 30 % jitter": ({"rate": 50.0, "jitter": 0.3}, 1.0),
    "200 Hz, 30 % jitter": ({"rate": 200.0, "jitter": 0.3}, 1.0),
    "no velocity columns": ({"with_velocities": False}, 1.0),
    "noise 1 mm / 1 N": ({"position_noise": 0.001, "theta_noise": 0.002, "force_noise": 1.0, "torque_noise": 0.3}, 1.0),
    "noise 8 mm / 5 N": ({"position_noise": 0.008, "theta_noise": 0.012, "force_noise": 5.0, "torque_noise": 2.5}, 1.0),
    "effects x 0.5": ({}, 0.5),
    "effects x 1.6": ({}, 1.6),
}


def _timing_log(name: str | None, form: str | None):
    """Return the 60 s, 100 Hz, 10 % jitter log of the timing rows (seed 0)."""
    rng = np.random.default_rng(0)
    p = random_cart(rng)
    eff = (random_effect(name, rng, p, 60.0, form),) if name else ()
    return simulate_hidden(p, eff, duration=60.0, rate=100.0, jitter=0.1, rng=rng).measured


def _process_time(log, repeats: int) -> float:
    """Return the median wall time of the whole process `cartpush diagnose LOG --json` (start-up included)."""
    exe = os.path.join(os.path.dirname(sys.executable), "cartpush")
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "log.csv")
        write_log(path, log)
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            subprocess.run([exe, "diagnose", path, "--json"], check=True, capture_output=True)
            times.append(time.perf_counter() - t0)
    return float(np.median(times))


def timing(repeats: int = 3, quiet: bool = False) -> list[dict]:
    """Return (and print unless ``quiet``) the median diagnose times of 60 s logs at 100 Hz, in process and whole process.

    Cases: no effect, swivelling casters, caster profile; the target (issue #18) is 8 s for the whole process.
    """
    rows = []
    for label, name, form in (
        ("no effect", None, None),
        ("swivelling casters", "caster_swivel", "swivel"),
        ("caster profile", "caster_swivel", "profile"),
    ):
        log = _timing_log(name, form)
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            diagnose(log)
            times.append(time.perf_counter() - t0)
        proc = _process_time(log, repeats)
        rows.append(
            {
                "case": label,
                "samples": len(log),
                "median_s": float(np.median(times)),
                "process_median_s": proc,
                "target_s": TARGET_S,
                "ratio_process_over_target": proc / TARGET_S,
            }
        )
    if not quiet:
        print(
            "| case | samples | in process, median [s] | whole process, median [s] | target [s] | ratio |\n"
            "|---|---|---|---|---|---|\n"
            + "\n".join(
                f"| 60 s log, 100 Hz, {r['case']} | {r['samples']} | {r['median_s']:.2f} | {r['process_median_s']:.2f} "
                f"| {TARGET_S:.0f} | {r['ratio_process_over_target']:.2f} |"
                for r in rows
            )
        )
    return rows


def run_cases(
    n: int,
    seed0: int = 1000,
    duration: float = 30.0,
    overrides: dict | None = None,
    scale: float = 1.0,
    label: str = "",
    classes: list[str] | None = None,
    caster_form: str | None = None,
) -> list[dict]:
    """Return one result dict per case: class, seed, first named, gap ratio, caster form, time."""
    out = []
    for ci, c in enumerate(CLASSES):
        if classes and c not in classes:
            continue
        for k in range(n):
            seed = seed0 + 1000 * ci + k
            h = random_case(
                None if c == "none" else c,
                np.random.default_rng(seed),
                duration=duration,
                scale=scale,
                caster_form=caster_form,
                **(overrides or {}),
            )
            t0 = time.perf_counter()
            r = diagnose(h.measured)
            dt = time.perf_counter() - t0
            first = r.names[0] if r.names else "none"
            form = ("swivel" if "trail" in h.effects[0].params else "profile") if c == "caster_swivel" else ""
            res = {
                "condition": label,
                "class": c,
                "seed": seed,
                "first": first,
                "names": r.names,
                "gap_before": r.gap_before,
                "gap_after": r.gap_after,
                "ratio": r.gap_after / r.gap_before if r.gap_before > 0 else float("nan"),
                "form": form,
                "time": dt,
            }
            out.append(res)
            print(
                f"{label} {c} {seed} {r.names} ratio {res['ratio']:.2f} gap {1000 * r.gap_before:.1f} mm "
                f"{form} {dt:.1f} s",
                file=sys.stderr,
                flush=True,
            )
    return out


def confusion_table(results: list[dict]) -> str:
    """Return the markdown confusion matrix (rows: hidden class, columns: first named effect or none)."""
    short = {c: c.replace("_", " ")[:10] for c in CLASSES}
    lines = [
        "| hidden \\ first named | " + " | ".join(short[c] for c in CLASSES) + " | n |",
        "|---" * (len(CLASSES) + 2) + "|",
    ]
    for c in CLASSES:
        rows = [r for r in results if r["class"] == c]
        counts = [sum(r["first"] == d for r in rows) for d in CLASSES]
        lines.append(f"| {c} | " + " | ".join(str(x) for x in counts) + f" | {len(rows)} |")
    return "\n".join(lines)


def rates_table(results: list[dict]) -> str:
    """Return per class: first named correct, gap halved (among all cases and among the correctly named)."""
    lines = [
        "| hidden | first named correct | gap_after <= 0.5 gap_before (all cases) | "
        "... (correctly named) | median gap_after/gap_before | median gap_before [mm] |",
        "|---|---|---|---|---|---|",
    ]
    for c in CLASSES:
        rows = [r for r in results if r["class"] == c]
        if not rows:
            continue
        ok = [r for r in rows if r["first"] == c]
        if c == "none":
            lines.append(
                f"| none | {len(ok)}/{len(rows)} = {len(ok) / len(rows):.0%} (empty list) | - | - | - | "
                f"{1000 * np.median([r['gap_before'] for r in rows]):.1f} |"
            )
            continue
        gapped = [r for r in rows if r["gap_before"] > 0]  # a log without any gap has nothing to halve
        halved = [r["ratio"] <= 0.5 for r in gapped]
        halved_ok = [r["ratio"] <= 0.5 for r in ok if r["gap_before"] > 0]
        zero = f" ({len(rows) - len(gapped)} with gap_before = 0)" if len(gapped) < len(rows) else ""
        lines.append(
            f"| {c} | {len(ok)}/{len(rows)} = {len(ok) / len(rows):.0%} | "
            f"{sum(halved)}/{len(gapped)} = {np.mean(halved) if gapped else float('nan'):.0%}{zero} | "
            f"{sum(halved_ok)}/{len(halved_ok)} = {np.mean(halved_ok) if halved_ok else float('nan'):.0%} | "
            f"{np.median([r['ratio'] for r in gapped]) if gapped else float('nan'):.2f} | "
            f"{1000 * np.median([r['gap_before'] for r in rows]):.1f} |"
        )
        if c == "caster_swivel":
            for form in ("profile", "swivel"):
                sub = [r for r in rows if r["form"] == form]
                gs = [r for r in sub if r["gap_before"] > 0]
                if sub:
                    lines.append(
                        f"| - {form} form | {sum(r['first'] == c for r in sub)}/{len(sub)} | "
                        f"{sum(r['ratio'] <= 0.5 for r in gs)}/{len(gs)} | | "
                        f"{np.median([r['ratio'] for r in gs]) if gs else float('nan'):.2f} | "
                        f"{1000 * np.median([r['gap_before'] for r in sub]):.1f} |"
                    )
    return "\n".join(lines)


def robust_table(results: list[dict]) -> str:
    """Return per condition: naming rate, empty-list rate on nominal logs, gap-halved rate (effects, gap > 0)."""
    lines = [
        "| condition | cases | first named correct (effects) | empty on nominal logs | gap halved (effects) | "
        "worst class (correct) |",
        "|---|---|---|---|---|---|",
    ]
    for cond in dict.fromkeys(r["condition"] for r in results):
        rows = [r for r in results if r["condition"] == cond]
        eff = [r for r in rows if r["class"] != "none"]
        nom = [r for r in rows if r["class"] == "none"]
        per = {
            c: np.mean([r["first"] == c for r in rows if r["class"] == c])
            for c in HIDDEN_NAMES
            if any(r["class"] == c for r in rows)
        }
        worst = min(per, key=per.get)
        eg = [r for r in eff if r["gap_before"] > 0]
        lines.append(
            f"| {cond} | {len(rows)} | {sum(r['first'] == r['class'] for r in eff)}/{len(eff)} | "
            f"{sum(r['first'] == 'none' for r in nom)}/{len(nom)} | "
            f"{sum(r['ratio'] <= 0.5 for r in eg)}/{len(eg)} | {worst} {per[worst]:.0%} |"
        )
    return "\n".join(lines)


#: targets of a 20-minute, 200 Hz log (issue 30, item 3)
SCALE_TARGET_S, SCALE_TARGET_MB = 60.0, 2048.0

_SCALE_CHILD = """
import json, resource, sys, time
from cart.diagnose import diagnose
from cart.logs import read_log
log = read_log(sys.argv[1])
t0 = time.perf_counter()
rep = diagnose(log)
ru = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"seconds": time.perf_counter() - t0, "names": rep.names, "samples": len(log.t),
                  "cpu_seconds": ru.ru_utime + ru.ru_stime, "peak_rss_mb": ru.ru_maxrss / 1024.0}))
"""


def scale_study(minutes: list[float], rate: float = 200.0, quiet: bool = False, seed: int = 5) -> list[dict]:
    """Return (and print unless ``quiet``) diagnose's wall time and peak RSS on effect-free logs of these lengths.

    Each log (hidden-effect test bed, ``rate`` Hz, 10 % jitter, ``seed``) is written to a file and
    diagnosed in a fresh process (the log already read: the wall time is diagnose's own; the CPU
    time, start-up and reading included, is the figure to read on a shared machine); the peak
    resident memory is that process's (``getrusage``), reading included.
    """
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for mins in minutes:
            rng = np.random.default_rng(seed)
            log = simulate_hidden(random_cart(rng), (), duration=60.0 * mins, rate=rate, jitter=0.1, rng=rng).measured
            path = os.path.join(d, f"long{mins:g}.csv")
            write_log(path, log)
            out = subprocess.run(
                [sys.executable, "-c", _SCALE_CHILD, path], check=True, capture_output=True, text=True
            ).stdout
            rows.append({"minutes": mins, **json.loads(out.strip().splitlines()[-1])})
    if not quiet:
        print("| log | samples | diagnose wall [s] | process CPU [s] | peak RSS [MB] | named | target (20 min) |")
        print("|---|---|---|---|---|---|---|")
        for r in rows:
            print(
                f"| {r['minutes']:g} min, {rate:g} Hz | {r['samples']} | {r['seconds']:.1f} | {r['cpu_seconds']:.1f} | "
                f"{r['peak_rss_mb']:.0f} | "
                f"{', '.join(r['names']) or 'none'} | {SCALE_TARGET_S:g} s, {SCALE_TARGET_MB:g} MB |"
            )
    return rows


def main(argv: list[str] | None = None) -> int:
    """Run the timing and the requested studies; print tables (or, with a bare --json, one JSON object)."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--study", type=int, default=0, help="cases per class for the confusion matrix (0: none)")
    ap.add_argument("--robust", type=int, default=0, help="cases per class for each robustness condition (0: none)")
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per timing case (medians)")
    ap.add_argument("--no-timing", action="store_true")
    ap.add_argument(
        "--json",
        nargs="?",
        const="-",
        default="",
        metavar="FILE",
        help="bare: print the figures as one JSON object; FILE: also write all per-case results there",
    )
    ap.add_argument("--classes", default="", help="comma-separated classes to run (default: all)")
    ap.add_argument("--caster-form", default=None, choices=("profile", "swivel"))
    ap.add_argument("--scale", default="", metavar="MINUTES", help="e.g. 1,5,20: time and memory of long 200 Hz logs")
    ap.add_argument("--scale-seed", type=int, default=5, help="the long logs' seed (--scale)")
    a = ap.parse_args(argv)
    quiet = a.json == "-"
    cls = [c for c in a.classes.split(",") if c] or None
    figures: dict[str, object] = {}
    if not a.no_timing:
        figures["timing"] = timing(a.repeats, quiet)
    if a.scale:
        figures["scale"] = scale_study([float(m) for m in a.scale.split(",") if m], quiet=quiet, seed=a.scale_seed)
    everything: list[dict] = []
    if a.study:
        res = run_cases(a.study, a.seed, label="default", classes=cls, caster_form=a.caster_form)
        everything += res
        figures["first_named_correct"] = {
            c: float(np.mean([r["first"] == c for r in res if r["class"] == c]))
            for c in CLASSES
            if any(r["class"] == c for r in res)
        }
        if not quiet:
            print("\n" + confusion_table(res) + "\n\n" + rates_table(res))
    if a.robust:
        rob: list[dict] = []
        for cond, (over, scale) in CONDITIONS.items():
            rob += run_cases(
                a.robust, a.seed, overrides=over, scale=scale, label=cond, classes=cls, caster_form=a.caster_form
            )
        everything += rob
        if not quiet:
            print("\n" + robust_table(rob))
    if quiet:
        print(json.dumps(figures))
    elif a.json:
        with open(a.json, "w") as f:
            json.dump(everything, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
