"""`cartpush track`: the WMRA paper's end-effector tracking experiments (§IV) in kinematic simulation."""

from __future__ import annotations

import argparse
import csv
import math
import sys
from pathlib import Path

from cartpush.cli import options

#: The paths of `wholebody.motion.experiments.PATHS` (kept here so --help imports nothing heavy).
PATHS = ("line", "sine")
#: Tolerance on the band radius before a run is reported as leaving the band (m).
BAND_TOLERANCE = 1e-3

EXAMPLE = """Examples:
  cartpush track line
  cartpush track sine --robot ridgeback_iiwa --band 0.7 --json
  cartpush track sine --out sine_run.csv
  cartpush track line --robot my_robot.toml   (a robot profile: its first arm tracks, docs/robots.md)

The end effector follows X = 90 t mm (line) or X = 90 t, Y = 1000 sin(0.1 t) mm (sine)
from its initial pose, orientation held, 100 Hz for 60 s (WMRA paper §IV, docs/papers.md).
--band R keeps the base origin within R metres of a centre sliding along world X at
90 mm/s (paper §VI safety band)."""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `track` subcommand."""
    p = subparsers.add_parser(
        "track",
        help="track the paper's straight-line or sinusoidal end-effector path (WMRA, Ridgeback+iiwa or a profile)",
        description="Resolved-rate QP tracking of an end-effector path by a mobile manipulator; prints "
        "position/orientation errors and joint-limit margins.\n\n" + EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("path", choices=PATHS, help="line: 90 mm/s along X; sine: plus 1 m sin(0.1 t) along Y")
    p.add_argument(
        "--robot",
        default="wmra",
        metavar="NAME|PROFILE.toml",
        help="a robot name (wmra, ridgeback_iiwa, ...) or a robot profile file (docs/robots.md); default wmra",
    )
    p.add_argument(
        "--band",
        type=float,
        default=None,
        metavar="RADIUS",
        help="safety band radius in metres (base origin within RADIUS of the sliding centre)",
    )
    p.add_argument("--duration", type=float, default=60.0, help="seconds (default 60)")
    p.add_argument("--rate", type=float, default=100.0, help="control rate in Hz (default 100)")
    p.add_argument("--out", type=Path, default=None, metavar="LOG.csv", help="write the run as CSV")
    p.add_argument("--json", action="store_true", help="print only a JSON object of the metrics")
    p.set_defaults(func=run)


def write_csv(result, path: Path) -> None:
    """Write one row per sample: time, base pose, arm joints, wheel rates, EE desired/actual position."""
    n_arm = result.x.shape[1] - 3
    n_w = result.wheel_rates.shape[1]
    header = (
        ["time_s", "base_x_m", "base_y_m", "base_theta_rad"]
        + [f"arm_q{i + 1}_rad" for i in range(n_arm)]
        + [f"wheel_rate{i + 1}_rad_s" for i in range(n_w)]
        + ["ee_desired_x_m", "ee_desired_y_m", "ee_desired_z_m", "ee_actual_x_m", "ee_actual_y_m", "ee_actual_z_m"]
    )
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for k in range(result.x.shape[0]):
            rates = result.wheel_rates[k] if k < result.steps else [math.nan] * n_w  # no input after the last sample
            w.writerow(
                [
                    f"{result.t[k]:.4f}",
                    *(f"{v:.9g}" for v in result.x[k]),
                    *(f"{v:.9g}" for v in rates),
                    *(f"{v:.9g}" for v in result.ee_desired[k]),
                    *(f"{v:.9g}" for v in result.ee_actual[k]),
                ]
            )


def run(args: argparse.Namespace) -> int:
    """Run the experiment; print a table or JSON; optionally write the CSV."""
    _check_options(args)
    from cart.jsonout import dumps_strict

    result = _run_experiment(args)
    if args.out is not None:
        write_csv(result, args.out)
    m = result.metrics()
    warnings = _band_warnings(m, args.band) + _singular_warnings(m)
    m["warnings"] = warnings
    for w in warnings:
        print(f"cartpush track: warning: {w}", file=sys.stderr)
    if args.json:
        print(dumps_strict(m))
        return 0
    _print_summary(args, m)
    return 0


def _check_options(args: argparse.Namespace) -> None:
    """Raise `options.OptionError` for a bad band, rate, duration or output file."""
    if args.band is not None:
        options.finite("--band", args.band, positive=True, maximum=1e3, why="a radius in metres")
    rate = options.finite("--rate", args.rate, positive=True, maximum=10_000.0, why="control rate in Hz")
    options.duration(args.duration, rate=rate)
    if args.duration * rate < 1.0:
        raise options.OptionError(f"--duration x --rate must give at least one step, got {args.duration * rate:g}")
    if args.out is not None:
        options.writable_file(args.out)
    check_robot(args.robot)


def check_robot(robot: str) -> None:
    """Raise `options.OptionError` (one line) unless `robot` names a mobile manipulator: a registered robot or a
    profile file with an arm on a wheeled base, checked against its URDF."""
    import robots
    from robots.errors import RobotError
    from robots.profiles import mobile_manipulators, profile

    try:
        prof = profile(robot)
        if prof.is_mobile_manipulator:
            robots.load(prof)  # the profile checked against its URDF: one line naming the key
    except RobotError as err:
        raise options.OptionError(f"--robot: {err}") from None
    if not prof.is_mobile_manipulator:
        raise options.OptionError(
            f"--robot {robot}: {prof.name!r} has no arm on a wheeled base, so it cannot track an end-effector "
            f"path; give {', '.join(mobile_manipulators())} or a profile with [[arms]] and wheel_joints"
        )


def _run_experiment(args: argparse.Namespace):
    """Return the tracking result, with a progress bar on stderr when it is a terminal."""
    from wholebody.motion.experiments import run_tracking

    bar = None
    if sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(total=int(round(args.duration * args.rate)), file=sys.stderr, desc=f"track {args.path}")
    try:
        return run_tracking(
            args.robot,
            args.path,
            args.band,
            duration=args.duration,
            rate=args.rate,
            progress=(lambda k: bar.update(1)) if bar is not None else None,
        )
    finally:
        if bar is not None:
            bar.close()


def _band_warnings(m: dict, band: float | None) -> list[str]:
    """Set ``m["band_respected"]`` when a band applies; return the warning when the base left it."""
    warnings = []
    if band is not None and m["max_band_distance_m"] is not None:
        excess = m["max_band_distance_m"] - band
        m["band_respected"] = bool(excess <= BAND_TOLERANCE)
        if excess > BAND_TOLERANCE:
            warnings.append(
                f"the base left the safety band: {m['max_band_distance_m']:.4f} m from the band "
                f"centre for a radius of {band:g} m ({excess:.4f} m outside); the path cannot be "
                f"followed within this band"
            )
    return warnings


#: Share of the steps near a singular arm pose above which a run warns that the arm hardly took part.
SINGULAR_SHARE = 0.1


def _singular_warnings(m: dict) -> list[str]:
    """Return the warning when the arm was near a singular pose in more than `SINGULAR_SHARE` of the steps (the
    base then did most of the motion; a profile robot starts from its arm's push_seed, else mid-range or, where
    that is singular, the best-conditioned of a few bent postures: `wholebody.motion.experiments.initial_state`)."""
    steps, singular = int(m["steps"]), int(m["singular_steps"])
    if steps == 0 or singular <= SINGULAR_SHARE * steps:
        return []
    return [
        f"the arm was near a singular pose in {singular} of {steps} steps, so the base did most of the motion; "
        "for a profile robot, give the arm a bent start posture (push_seed in its [[arms]] table)"
    ]


#: A ratio this close to 1 means the limit was reached (the QP keeps rates and the band within their bounds).
AT_LIMIT = 0.999


def _bound_limits(m: dict, band: float | None) -> list[str]:
    """Return the limits the run reached: the band's edge, joint or wheel rate limits, joint position limits."""
    reached = []
    if band is not None and m["max_band_distance_m"] is not None and m["max_band_distance_m"] >= band - 1e-3:
        reached.append(
            f"the base reached the {band:g} m band's edge ({m['max_band_distance_m']:.4f} m from its centre)"
        )
    if m["max_joint_speed_ratio"] >= AT_LIMIT:
        reached.append("an arm joint reached its rate limit")
    if m["max_wheel_speed_ratio"] >= AT_LIMIT:
        reached.append("a wheel reached its rate limit")
    if m["min_joint_limit_margin_rad"] <= 1e-3:
        reached.append("an arm joint reached its position limit")
    return reached


def flag_reasons(m: dict, band: float | None) -> list[str]:
    """Return why steps were flagged (one line each) and whether it cost tracking accuracy; [] when none were."""
    lines = []
    n, steps = m["saturated_steps"], max(1, m["steps"])
    if n:
        reached = _bound_limits(m, band)
        cause = "; ".join(reached) if reached else "a limit or a singular direction"
        lines.append(
            f"saturated = the QP could not give the commanded hand velocity exactly (|J u - v_ref| > 1e-3 m/s, rad/s) "
            f"in {n} of {m['steps']} steps ({100 * n / steps:.0f} %): {cause}"
        )
        worst = m["max_position_error_m"] * 1e3
        effect = "the hand still tracked the path" if worst < 1.0 else "the hand fell behind the path"
        lines.append(f"{effect}: max position error {worst:.4f} mm")
    if m["singular_steps"]:
        lines.append(
            f"singular = the arm's Jacobian lost rank (sigma_min below threshold) in {m['singular_steps']} steps"
        )
    if m["solver_failures"]:
        lines.append(f"solver failures = no QP solution in {m['solver_failures']} steps (the previous rates were held)")
    return lines


def _print_summary(args: argparse.Namespace, m: dict) -> None:
    """Print the metrics as a table."""
    band = "free" if args.band is None else f"band R = {args.band:g} m"
    print(f"{m['robot']} {m['path']} ({band}), {m['steps']} steps at {1 / m['dt']:g} Hz")
    print(f"  max position error     {m['max_position_error_m'] * 1e3:10.4f} mm")
    print(f"  RMS position error     {m['rms_position_error_m'] * 1e3:10.4f} mm")
    print(f"  max orientation error  {m['max_orientation_error_rad']:10.2e} rad")
    print(f"  min joint-limit margin {m['min_joint_limit_margin_rad']:10.4f} rad")
    print(f"  max |rate|/limit       joints {m['max_joint_speed_ratio']:.3f}, wheels {m['max_wheel_speed_ratio']:.3f}")
    if m["max_band_distance_m"] is not None:
        print(
            f"  max base distance from band centre {m['max_band_distance_m']:.4f} m"
            + ("" if m.get("band_respected", True) else f"  ** OUTSIDE the {args.band:g} m band **")
        )
    print(
        f"  flagged steps: singular {m['singular_steps']}, saturated {m['saturated_steps']}, "
        f"solver failures {m['solver_failures']}"
    )
    for line in flag_reasons(m, args.band):
        print(f"    {line}")
    if args.out is not None:
        print(f"  wrote {args.out}")
