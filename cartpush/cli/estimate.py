"""`cartpush estimate LOG`: the cart's mass, CoM, inertia and viscous coefficients from a measured log."""

from __future__ import annotations

import argparse
import math
from typing import Any

from cartpush.cli.import_bag import add_topic_options, topic_options

#: Mean NIS above which the EKF's innovations do not fit the 6-dof measurement (about 6 expected).
NIS_MISFIT = 18.0

DESCRIPTION = """\
Estimate the cart's inertial parameters (mass, CoM, inertia about the CoM) and its
two viscous coefficients (forward/lateral N s/m, yaw N m s/rad) from a log in the
project's cart log format (CSV or .csv.gz; velocity columns optional).

--method ls (default): filtered-regressor least squares over the whole log; the
  noisy logged wrench is the regression's output, so wrench noise does not bias
  the estimate; noise levels, filter band and uncertainty come from the log itself.
--method ekf: the paper's augmented-state EKF (eq. 8-20) with a multi-start; the
  wrench is its input, so wrench noise biases the mass upwards.

The output says whether the model fits the log (`model_fits`, `nis_mean`: the
EKF's mean normalized innovation with these parameters, ~6 when it fits) and
lists warnings (weak excitation, misfit: then run `cartpush diagnose`).

A ROS bag (ROS 1 .bag, ROS 2 folder, .mcap) is converted in memory with the same
options as `cartpush import` (--pose-topic, --wrench-topic, ...).

Example:
  cartpush estimate push.csv --json
  cartpush estimate run.bag --pose-topic /mocap/cart --wrench-topic /ft_sensor/wrench
  cartpush estimate push.csv --method ekf --mass-guess 25 --com-guess 0.3 0
"""


def register(subparsers) -> None:
    """Add the `estimate` subcommand."""
    parser = subparsers.add_parser(
        "estimate",
        help="estimate cart mass/CoM/inertia/damping from a log",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("log", metavar="LOG", help="cart log (.csv or .csv.gz) or a ROS bag (with the topic options)")
    parser.add_argument(
        "--method",
        choices=("ls", "ekf"),
        default="ls",
        help="ls: whole-log least squares (default); ekf: the paper's EKF",
    )
    parser.add_argument(
        "--mass-guess", type=float, default=20.0, metavar="KG", help="EKF only: initial mass (default 20)"
    )
    parser.add_argument(
        "--com-guess",
        type=float,
        nargs=2,
        default=(0.0, 0.0),
        metavar=("DX", "DY"),
        help="EKF only: initial CoM in the cart frame {b} (default 0 0)",
    )
    parser.add_argument(
        "--sigma-guess",
        type=float,
        default=1.0,
        metavar="NS_PER_M",
        help="EKF only: initial viscous coefficients (default 1)",
    )
    parser.add_argument("--json", action="store_true", help="print only JSON")
    add_topic_options(parser)
    parser.set_defaults(func=run)


def _check_guesses(args: argparse.Namespace) -> None:
    from cart.errors import CartError

    if not (math.isfinite(args.mass_guess) and args.mass_guess > 0):
        raise CartError(f"--mass-guess must be a positive number of kg, got {args.mass_guess}")
    if not all(math.isfinite(v) for v in args.com_guess):
        raise CartError(f"--com-guess must be two finite numbers of metres, got {args.com_guess}")
    if not (math.isfinite(args.sigma_guess) and args.sigma_guess >= 0):
        raise CartError(f"--sigma-guess must be a non-negative number, got {args.sigma_guess}")


def np_linalg_error() -> type:
    """Return numpy's LinAlgError class (imported lazily)."""
    import numpy as np

    return np.linalg.LinAlgError


def _run_ls(log) -> dict[str, Any]:
    from cart.identify import identify, innovation_check

    from cart.errors import CartError

    res = identify(log)
    p = res.params
    warnings = list(getattr(log, "warnings", ())) + list(res.warnings)
    try:
        nis, rejected = innovation_check(log, p, res.noise)
    except (CartError, ArithmeticError, np_linalg_error()) as exc:
        nis, rejected = float("nan"), 0
        warnings.append(f"the EKF innovation check could not run on this log ({exc})")
    fits = res.model_fits
    if math.isfinite(nis) and nis > NIS_MISFIT and fits:
        fits = False
        warnings.append(f"the EKF's innovations do not fit (mean NIS {nis:.1f}, ~6 expected); run `cartpush diagnose`")
    return {
        **_parameters("ls", p, res.std),
        "nis_mean": nis,
        "model_fits": fits,
        "residual_ratio": list(res.residual_ratio),
        "cutoff_hz": res.cutoff_hz,
        "coulomb_resistance": {"force": res.coulomb["force"], "torque": res.coulomb["torque"]},
        "noise_std": res.noise,
        "samples_used": res.samples_used,
        "gaps": res.gaps,
        "rejected_samples": rejected,
        "warnings": warnings,
    }


def _parameters(method: str, p, std: dict) -> dict[str, Any]:
    """Return the leading fields of the JSON result: the method, the estimated parameters and their std."""
    return {
        "method": method,
        "mass": p.m,
        "com": [p.dx, p.dy],
        "inertia": p.I,
        "sigma": p.sigma,
        "sigma_yaw": p.sigma_yaw,
        "std": std,
    }


def _run_ekf(log, args: argparse.Namespace) -> dict[str, Any]:
    from cart.ekf import estimate_from_log
    from cart.errors import LogFormatError
    from cart.params import CartParams

    guess = CartParams(args.mass_guess, args.com_guess[0], args.com_guess[1], 0.1 * args.mass_guess, args.sigma_guess)
    try:
        est = estimate_from_log(log, guess, estimate_sigma=True)
    except (FloatingPointError, TypeError) as exc:
        raise LogFormatError(f"{args.log}: the EKF diverged on this log ({exc})") from None
    p = est.params
    if not all(math.isfinite(v) for v in (p.m, p.dx, p.dy, p.I, p.sigma, p.sigma_yaw)):
        raise LogFormatError(f"{args.log}: the EKF diverged on this log (non-finite estimate)")
    fits = bool(math.isfinite(est.mean_nis) and est.mean_nis < NIS_MISFIT)
    warnings = list(getattr(log, "warnings", ()))
    warnings += (
        []
        if fits
        else [
            f"the EKF's innovations do not fit (mean NIS {est.mean_nis:.1f}, ~6 expected): "
            "the std understates the error; run `cartpush diagnose`"
        ]
    )
    return {
        **_parameters("ekf", p, est.std),
        "nis_mean": est.mean_nis,
        "model_fits": fits,
        "velocities_estimated": est.velocities_estimated,
        "rejected_samples": int(getattr(est, "rejected_samples", 0)),
        "gaps": int(getattr(est, "gaps", 0)),
        "warnings": warnings,
    }


def check_args(args: argparse.Namespace) -> None:
    """Raise a CartpushError for options the command cannot use (before reading any log)."""
    _check_guesses(args)


def result_for(log, args: argparse.Namespace) -> dict[str, Any]:
    """Return the JSON dict `cartpush estimate --json` prints for ``log`` (also each result of `cartpush batch`)."""
    return _run_ls(log) if args.method == "ls" else _run_ekf(log, args)


def run(args: argparse.Namespace) -> int:
    """Estimate the parameters of the log and print them; return 0."""
    from cart.jsonout import dumps_strict
    from cartpush.ros import load_any

    _check_guesses(args)
    log = load_any(args.log, **topic_options(args))
    out = result_for(log, args)
    if args.json:
        print(dumps_strict(out))
        return 0
    s = out["std"]
    print(f"log        {args.log} ({len(log)} samples, {log.t[-1] - log.t[0]:.2f} s; method {out['method']})")
    print(f"mass       {out['mass']:9.3f} +- {s['mass']:.3f} kg")
    print(f"CoM dx     {out['com'][0]:9.4f} +- {s['com'][0]:.4f} m   (in the cart frame {{b}})")
    print(f"CoM dy     {out['com'][1]:9.4f} +- {s['com'][1]:.4f} m")
    print(f"inertia    {out['inertia']:9.4f} +- {s['inertia']:.4f} kg m^2 (about the CoM)")
    print(f"sigma      {out['sigma']:9.4f} +- {s['sigma']:.4f} N s/m (forward/lateral)")
    print(f"sigma_yaw  {out['sigma_yaw']:9.4f} +- {s['sigma_yaw']:.4f} N m s/rad (yaw)")
    print(f"model fits {'yes' if out['model_fits'] else 'NO'} (mean NIS {out['nis_mean']:.2f}, ~6 when it fits)")
    for w in out["warnings"]:
        print(f"warning: {w}")
    return 0
