"""`cartpush estimate LOG`: the cart EKF on a measured log; prints mass, CoM, inertia, sigma and their std."""
from __future__ import annotations

import argparse
import json
import math

from cart.ekf import estimate_from_log
from cart.errors import CartError, LogFormatError
from cart.logs import read_log
from cart.params import CartParams

DESCRIPTION = """\
Estimate the cart's inertial parameters (mass, CoM, inertia about the CoM,
viscous coefficient) from a log in the project's cart log format (CSV or
.csv.gz; velocity columns optional, estimated from the pose when absent) with
the augmented-state EKF. The measurement noise is estimated from the log.

Example:
  cartpush estimate push.csv --mass-guess 25 --com-guess 0.3 0 --json
"""


def register(subparsers) -> None:
    """Add the `estimate` subcommand."""
    parser = subparsers.add_parser("estimate", help="estimate cart mass/CoM/inertia from a log (EKF)",
                                   description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("log", metavar="LOG", help="cart log (.csv or .csv.gz)")
    parser.add_argument("--mass-guess", type=float, default=20.0, metavar="KG", help="initial mass (default 20)")
    parser.add_argument("--com-guess", type=float, nargs=2, default=(0.0, 0.0), metavar=("DX", "DY"),
                        help="initial CoM in the cart frame {b} (default 0 0)")
    parser.add_argument("--sigma-guess", type=float, default=1.0, metavar="NS_PER_M",
                        help="initial viscous coefficient (default 1)")
    parser.add_argument("--json", action="store_true", help="print only JSON")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the EKF over the log and print the estimate; return 0."""
    if not (math.isfinite(args.mass_guess) and args.mass_guess > 0):
        raise CartError(f"--mass-guess must be a positive number of kg, got {args.mass_guess}")
    log = read_log(args.log)
    guess = CartParams(args.mass_guess, args.com_guess[0], args.com_guess[1], 0.1 * args.mass_guess,
                       max(args.sigma_guess, 0.0))
    try:
        est = estimate_from_log(log, guess, estimate_sigma=True)
    except FloatingPointError as exc:  # pragma: no cover - numerical breakdown on absurd data
        raise LogFormatError(f"{args.log}: the EKF diverged on this log ({exc})") from None
    p = est.params
    values = [p.m, p.dx, p.dy, p.I, p.sigma]
    if not all(math.isfinite(v) for v in values):
        raise LogFormatError(f"{args.log}: the EKF diverged on this log (non-finite estimate)")
    out = {"mass": p.m, "com": [p.dx, p.dy], "inertia": p.I, "sigma": p.sigma, "std": est.std}
    if args.json:
        print(json.dumps(out))
        return 0
    s = est.std
    print(f"log        {args.log} ({len(log)} samples, {log.t[-1] - log.t[0]:.2f} s"
          f"{', velocities estimated from the pose' if est.velocities_estimated else ''})")
    print(f"mass       {p.m:9.3f} +- {s['mass']:.3f} kg")
    print(f"CoM dx     {p.dx:9.4f} +- {s['com'][0]:.4f} m")
    print(f"CoM dy     {p.dy:9.4f} +- {s['com'][1]:.4f} m")
    print(f"inertia    {p.I:9.4f} +- {s['inertia']:.4f} kg m^2 (about the CoM)")
    print(f"sigma      {p.sigma:9.4f} +- {s['sigma']:.4f} N s/m")
    print(f"mean NIS   {est.mean_nis:9.3f} (6 expected for a consistent filter)")
    return 0
