"""`cartpush diagnose LOG`: find where the cart model and a log disagree, name the missing effect(s)."""
from __future__ import annotations

import argparse
import json

from cart.diagnose import diagnose, plot_diagnosis
from cart.logs import read_log


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
    p.add_argument("--threshold", type=float, default=10.0, help="Delta BIC needed to name an effect (default 10)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Diagnose the log; print a summary (or JSON); write plots with --out."""
    log = read_log(args.log)
    report = diagnose(log, threshold=args.threshold)
    paths = plot_diagnosis(report, args.out) if args.out else []
    if args.json:
        out = report.to_dict()
        if paths:
            out["plots"] = paths
        print(json.dumps(out))
        return 0
    print(report.summary())
    for p in paths:
        print(f"wrote {p}")
    return 0
