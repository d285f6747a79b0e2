"""`cartpush diagnose LOG`: find where the cart model and a log disagree, name the missing effect(s)."""
from __future__ import annotations

import argparse

from wholebody.cli import options


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `diagnose` subcommand."""
    p = subparsers.add_parser(
        "diagnose",
        help="fit the cart model to a log, find significant discrepancies, name the missing effects",
        description="Fit the nominal cart model (mass, CoM, inertia, viscous sigma) to a cart log, replay it over\n"
        "1 s horizons to find windows where it disagrees significantly with the measured motion, then try\n"
        "each candidate effect (coulomb_friction, caster_swivel, wrench_bias, payload_change, floor_slope,\n"
        "time_delay, lateral_slip), keep the ones with Delta BIC > threshold and report the gap before/after.\n\n"
        "Example:\n  cartpush diagnose run.csv\n  cartpush diagnose run.csv.gz --json --out plots/",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("log", help="cart log (LOG_FORMAT.md CSV, .csv or .csv.gz)")
    p.add_argument("--json", action="store_true", help="print JSON only")
    p.add_argument("--out", metavar="DIR", help="write replay.png and residuals.png into DIR")
    p.add_argument("--threshold", type=float, default=10.0,
                   help="Delta BIC needed to name an effect, a finite number >= 0 (default 10)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Diagnose the log; print a summary (or JSON); write plots with --out."""
    options.finite("--threshold", args.threshold, nonnegative=True, maximum=1e6,
                   why="a Delta BIC: negative or NaN would name effects with negative evidence")
    if args.out:
        options.writable_dir(args.out)
    import numpy as np

    from cart.diagnose import DiagnoseError, diagnose, plot_diagnosis
    from cart.jsonout import dumps_strict
    from cart.logs import read_log

    log = read_log(args.log)
    try:
        report = diagnose(log, threshold=args.threshold)
    except (np.linalg.LinAlgError, FloatingPointError) as exc:
        # degenerate data (no motion, no excitation, implausible units) breaks the fits' linear algebra
        notes = f"; the reader noted: {log.warnings[0]}" if log.warnings else ""
        raise DiagnoseError(f"{args.log}: the model fit broke down numerically on this log ({exc}): it is "
                            f"degenerate for diagnosis (no motion or excitation, or implausible units){notes}") from None
    paths = plot_diagnosis(report, args.out) if args.out else []
    if args.json:
        out = report.to_dict()
        if paths:
            out["plots"] = paths
        out["warnings"] = list(out.get("warnings", [])) + list(log.warnings)
        print(dumps_strict(out))
        return 0
    for w in log.warnings:
        print(f"warning: {w}")
    print(report.summary())
    for p in paths:
        print(f"wrote {p}")
    return 0
