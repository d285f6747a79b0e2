"""`cartpush diagnose LOG`: find where the cart model and a log disagree, name the missing effect(s)."""

from __future__ import annotations

import argparse
import contextlib
import sys
import threading
from collections.abc import Callable, Iterator, Sequence

from cartpush.cli import options
from cartpush.cli.import_bag import add_topic_options, topic_options
from wholebody.progress import show_progress


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `diagnose` subcommand."""
    p = subparsers.add_parser(
        "diagnose",
        help="fit the cart model to a log, find significant discrepancies, name the missing effects",
        description="Fit the nominal cart model (mass, CoM, inertia, viscous sigma) to a cart log, replay it over\n"
        "1 s horizons to find windows where it disagrees significantly with the measured motion, then try\n"
        "each candidate effect (coulomb_friction, caster_swivel, wrench_bias, payload_change, floor_slope,\n"
        "time_delay, lateral_slip), keep the ones with Delta BIC > threshold whose replay shrinks the gap, and\n"
        "say why each was named or not (a broken no-slip constraint puts lateral_slip first). Multi-rate tables,\n"
        "logging gaps and clock offsets are handled; a wrench given in the cart frame is refused.\n\n"
        "Example:\n  cartpush diagnose run.csv\n  cartpush diagnose run.csv.gz --json --out plots/",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "log", help="cart log (docs/log_format.md CSV, .csv or .csv.gz) or a ROS bag (with the topic options)"
    )
    p.add_argument("--json", action="store_true", help="print JSON only")
    p.add_argument("--out", metavar="DIR", help="write replay.png and residuals.png into DIR")
    p.add_argument(
        "--threshold",
        type=float,
        default=10.0,
        help="Delta BIC needed to name an effect, a finite number >= 0 (default 10)",
    )
    add_topic_options(p)
    p.set_defaults(func=run)


def check_args(args: argparse.Namespace) -> None:
    """Raise a CartpushError for options the command cannot use (before reading any log)."""
    options.finite(
        "--threshold",
        args.threshold,
        nonnegative=True,
        maximum=1e6,
        why="a Delta BIC: negative or NaN would name effects with negative evidence",
    )


def _report(log, args: argparse.Namespace):
    """Return the diagnosis report of ``log`` (a DiagnoseError when the fits break down numerically)."""
    import numpy as np

    from cart.diagnose import DiagnoseError, diagnose

    try:
        return diagnose(log, threshold=args.threshold)
    except (np.linalg.LinAlgError, FloatingPointError) as exc:
        # degenerate data (no motion, no excitation, implausible units) breaks the fits' linear algebra
        notes = f"; the reader noted: {log.warnings[0]}" if log.warnings else ""
        raise DiagnoseError(
            f"{args.log}: the model fit broke down numerically on this log ({exc}): it is "
            f"degenerate for diagnosis (no motion or excitation, or implausible units){notes}"
        ) from None


def _to_json(report, log, paths=()) -> dict:
    out = report.to_dict()
    if paths:
        out["plots"] = list(paths)
    out["warnings"] = list(out.get("warnings", [])) + list(log.warnings)
    return out


def result_for(log, args: argparse.Namespace) -> dict:
    """Return the JSON dict `cartpush diagnose --json` prints for ``log`` (also each result of `cartpush batch`)."""
    return _to_json(_report(log, args), log)


@contextlib.contextmanager
def stage_bar(stages: Sequence[str], enabled: bool) -> Iterator[Callable[[str], None]]:
    """Yield ``step(name)``, which starts the named stage of a tqdm bar on stderr (a no-op when not `enabled`).

    The bar shows the stage, how many stages are done and the elapsed time,
    refreshed twice a second while a long stage (the fits) runs.
    """
    if not enabled:
        yield lambda name: None
        return
    from tqdm import tqdm

    bar = tqdm(total=len(stages), file=sys.stderr, bar_format="{desc} {n}/{total} stages [{elapsed}]", leave=False)
    started = [False]

    def step(name: str) -> None:
        if started[0]:
            bar.update(1)
        started[0] = True
        bar.set_description_str(f"diagnose: {name}")

    stop = threading.Event()
    ticker = threading.Thread(target=lambda: [bar.refresh() for _ in iter(lambda: stop.wait(0.5), True)], daemon=True)
    ticker.start()
    try:
        yield step
    finally:
        stop.set()
        ticker.join()
        bar.close()


def run(args: argparse.Namespace) -> int:
    """Diagnose the log; print a summary (or JSON); write plots with --out."""
    from cartpush.cli.estimate import _one_blas_thread

    _one_blas_thread()  # before numpy loads, as `estimate` does
    check_args(args)
    if args.out:
        options.writable_dir(args.out)
    from cart.diagnose import plot_diagnosis
    from cart.jsonout import dumps_strict
    from cartpush.ros import load_any

    stages = ["reading the log", "fitting the model and the candidate effects"] + (["plotting"] if args.out else [])
    with stage_bar(stages, enabled=show_progress(args.json)) as step:
        step(stages[0])
        log = load_any(args.log, **topic_options(args))
        step(stages[1])
        report = _report(log, args)
        if args.out:
            step(stages[2])
        paths = plot_diagnosis(report, args.out) if args.out else []
    if args.json:
        print(dumps_strict(_to_json(report, log, paths)))
        return 0
    for w in log.warnings:
        print(f"warning: {w}")
    print(report.summary())
    for p in paths:
        print(f"wrote {p}")
    return 0
