"""`cartpush push`: the closed loop — a mobile manipulator (Ridgeback + iiwa, the WMRA, a profile robot) pushes the cart, the estimator closes it."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from cartpush.cli import options
from cartpush.errors import OptionError
from wholebody.errors import WholeBodyError

if TYPE_CHECKING:
    from wholebody.contacts.allocation import ArmLimits
    from wholebody.push.base_settings import BasePlanSettings
    from wholebody.push.load_change import LoadChange
    from wholebody.push.reference_clock import TimeScaling

JSON_FIELDS = (
    "tracking_rms_mm",
    "tracking_max_mm",
    "arm_torque_rms_nm",
    "arm_torque_peak_nm",
    "mass_error_final_kg",
    "com_error_final_m",
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `push` subcommand."""
    p = subparsers.add_parser(
        "push",
        help="simulate the mobile manipulator(s) pushing the cart with the parameter estimate in the loop",
        description=(
            "Simulate a mobile manipulator (default the Ridgeback + iiwa 14) pushing the shopping cart along Traj. 1 or 2 of the cart\n"
            "paper: cart controller (with the online estimate) -> wrench allocation QP -> arm torques\n"
            "(Pinocchio, checked against the iiwa's limits) -> whole-body tracking of the handle ->\n"
            "cart dynamics (or --plant mujoco) -> noisy motion capture and F/T sensing -> estimator. True cart 20 kg,\n"
            "CoM (30, 15) cm in the cart frame; the estimator starts at 16 kg, CoM (30, 0) cm.\n\n"
            "With --robot wmra the wheelchair-mounted arm pushes: its differential-drive base never slides\n"
            "sideways (wheel-rate input), follows the cart with a look-ahead point, and the contact is\n"
            "chosen only where the arm holds it with margin from the wheelchair's place behind the cart.\n\n"
            "Tracking errors are in mm, CoM errors in cm (--json keeps its fields' units: *_mm, *_m); under the\n"
            "table (and as mass_unobservable_s / com_unobservable_s in --json) the stretches where the estimate's\n"
            "1-sigma of the mass or CoM grew (no new information: the estimate is held, not updated), then the\n"
            "arm torque against its limits (a warning on stderr when over). The --html page plays when opened\n"
            "(pause button and legend in its bottom-left corner).\n"
            "A progress bar shows on a terminal (never with --json or when stderr is not a terminal).\n\n"
            "Example:\n  cartpush push --trajectory 2 --contact optimal --json\n"
            "  cartpush push --robot wmra --trajectory 2 --json\n"
            "  cartpush push --plant mujoco --trajectory 1 --json\n"
            "  cartpush push --plant mujoco --cart-model my_cart.xml --json\n"
            "  cartpush push --robot my_robot.toml --arms 2 --json   (a robot profile, docs/robots.md)\n"
            "  cartpush push --trajectory 1 --load-change 12:+10 --json   (10 kg put in at 12 s)\n"
            "  cartpush push --no-estimation --out report/ --html report/push.html"
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--robot",
        default="ridgeback_iiwa",
        metavar="NAME|PROFILE.toml",
        help="the pushing robot: a registered name (ridgeback_iiwa: holonomic base, default; wmra: differential\n"
        "drive) or a robot profile file (docs/robots.md)",
    )
    p.add_argument("--trajectory", type=int, default=2, help="paper trajectory: 1 (straight) or 2 (turns); default 2")
    p.add_argument("--arms", type=int, default=1, help="1 or 2 mobile manipulators (default 1)")
    p.add_argument(
        "--no-estimation",
        action="store_true",
        help="freeze the parameters at the initial guess (wrong mass) instead of estimating them",
    )
    p.add_argument(
        "--estimator",
        default="online",
        choices=("online", "ekf"),
        help="the parameter estimator: online (recursive least squares with the wrench as the regression's output; "
        "load changes and run-off reported; default) or ekf (the cart paper's EKF)",
    )
    p.add_argument(
        "--plant",
        default=None,
        choices=("kinematic", "mujoco"),
        help="what answers the controller: kinematic (ideal servos, the exact cart model; default) or mujoco "
        "(robots and cart in the MuJoCo physics engine; the grips are welds, so the contact is fixed; the default "
        "with --cart-model)",
    )
    p.add_argument(
        "--cart-model",
        type=Path,
        default=None,
        metavar="FILE.xml",
        help="push this MJCF cart (the contract is in docs/mujoco.md) instead of the shopping cart, on the MuJoCo "
        "plant",
    )
    p.add_argument(
        "--contact",
        default=None,
        help="fixed (y=-0.2 m, or -0.2/+0.2 for 2 arms) or optimal (default optimal; fixed with --plant mujoco)",
    )
    p.add_argument(
        "--contact-y",
        type=float,
        nargs="+",
        default=None,
        metavar="Y",
        help="fixed contact point(s) y on the handle in m, within its span ([-0.25, 0.25] on the shopping cart)",
    )
    _auto_on_off(
        p,
        "--base-plan",
        "plan a holonomic one-arm base's place ahead within its wheel limits where the rigid place behind\n"
        "the handle breaks them (wholebody/push/base_plan.py; Traj. 2: about 7 s CPU). auto (default): with\n"
        "--plant mujoco only; --base-plan alone: on",
    )
    _auto_on_off(
        p,
        "--tip-bound",
        "keep every wheel of the cart loaded: the allocation pushes sideways only as hard as the cart stands\n"
        "and may press down on the handle (wholebody/contacts/support.py). auto (default): with --plant mujoco only",
    )
    p.add_argument(
        "--grip-torque-arm",
        type=float,
        default=None,
        metavar="M",
        help="the yaw, roll and pitch torque one hand may apply per N of normal load, in m (the allocation's\n"
        "GraspModel.torque_arm; default 0.02: 8 N m at the grip's 2 x 200 N squeeze). A firmer grip (0.1) makes\n"
        "the cart's yaw torque at the wrist instead of with lateral force at the handle's height",
    )
    p.add_argument(
        "--load-change",
        action="append",
        default=None,
        metavar="T:+M[@X,Y]",
        help="put M kg into the cart at T s (-M: take M kg out), at (X, Y) m in the cart frame {b} (default: at its\n"
        "centre of mass); repeatable. A load put in takes the cart's momentum (docs/push.md); --json gives\n"
        "load_changes_true beside the estimator's load_changes, and what_happened says whether each was found",
    )
    p.add_argument(
        "--look-ahead",
        type=float,
        default=0.0,
        metavar="S",
        help="MuJoCo plant: slow the reference before a stretch of the next S s of the path that the arms cannot\n"
        "give at speed (wholebody.push.reference_clock.admissible_rate; default 0: off)",
    )
    p.add_argument("--duration", type=float, default=30.0, help="trajectory duration in s (default 30)")
    p.add_argument("--initial-mass", type=float, default=16.0, help="initial mass estimate in kg (default 16)")
    p.add_argument(
        "--initial-com",
        default="0.3,0",
        metavar="DX,DY",
        help="initial CoM estimate in m in the cart frame {b} (default 0.3,0: the shopping cart's guess; for a cart\n"
        "file, somewhere between its wheels)",
    )
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    p.add_argument("--json", action="store_true", help="print JSON only")
    p.add_argument("--html", type=Path, default=None, help="write a Meshcat animation of the run to this file")
    p.add_argument("--out", type=Path, default=None, help="write the figures and the run's log (LOG_FORMAT) here")
    p.set_defaults(func=run)


def config_from_args(args: argparse.Namespace):
    """Return the PushConfig of the parsed arguments (bad values raise WholeBodyError)."""
    from robots.errors import RobotError
    from robots.profiles import mobile_manipulators, profile
    from wholebody.push import PushConfig

    import robots

    try:
        prof = profile(args.robot)  # a registered name or a profile file
        robots.load(prof)  # the profile checked against its URDF: one line naming the key (exit 2)
    except RobotError as err:
        raise WholeBodyError(f"--robot: {err}") from None
    if not prof.is_mobile_manipulator:
        why = "it has no arm ([[arms]])" if not prof.arms else 'its base is "none" (give base and wheel_joints)'
        raise WholeBodyError(
            f"--robot must be a robot with an arm on a wheeled base ({', '.join(mobile_manipulators())} or a "
            f"profile file): {args.robot!r} is not, {why}"
        )
    if args.plant is None:  # a cart file is a MuJoCo model: pushing it means the MuJoCo plant
        args.plant = "mujoco" if args.cart_model is not None else "kinematic"
    if args.contact is None:
        args.contact = "fixed" if args.plant == "mujoco" else "optimal"
    if args.cart_model is not None:
        if args.plant != "mujoco":
            raise WholeBodyError("--cart-model needs the MuJoCo plant (leave --plant out, or --plant mujoco)")
        if args.cart_model.is_dir():
            raise WholeBodyError(f"--cart-model {args.cart_model}: is a directory; give the MJCF file")
        if not args.cart_model.is_file():
            raise WholeBodyError(f"--cart-model {args.cart_model}: no such file")
    if args.contact not in ("fixed", "optimal"):
        raise WholeBodyError(f"--contact must be 'fixed' or 'optimal', got {args.contact!r}")
    if args.trajectory not in (1, 2):
        raise WholeBodyError(f"--trajectory must be 1 or 2, got {args.trajectory}")
    if args.arms not in (1, 2):
        raise WholeBodyError(f"--arms must be 1 or 2, got {args.arms}")
    options.duration(args.duration, minimum=8.0, why="ramp up, cruise, stop", rate=1000.0)
    _check_initial_mass(args.initial_mass)
    initial_com = parse_initial_com(args.initial_com)
    options.seed(args.seed)
    for v in args.contact_y or ():
        options.finite("--contact-y", v)
    fixed_contact_y: tuple[float, ...] | None = None
    if args.contact_y is not None:
        ys = tuple(args.contact_y)
        lo, hi = _handle_span(args.cart_model)
        if len(ys) != args.arms or any(not lo - 1e-9 <= v <= hi + 1e-9 for v in ys):
            raise WholeBodyError(
                f"--contact-y needs {args.arms} value(s) within the handle's [{lo:g}, {hi:g}] m, got {list(ys)}"
            )
        if len(ys) == 2 and abs(ys[1] - ys[0]) < 0.2:
            raise WholeBodyError("two contact points must be at least 0.2 m apart")
        fixed_contact_y = ys
    elif args.arms == 2:
        fixed_contact_y = (-0.2, 0.2)
    return PushConfig(
        trajectory=args.trajectory,
        n_arms=args.arms,
        estimation=not args.no_estimation,
        contact=args.contact,
        duration=args.duration,
        initial_mass=args.initial_mass,
        initial_com=initial_com,
        seed=args.seed,
        robot=args.robot,
        plant=args.plant,
        estimator=args.estimator,
        cart_model=None if args.cart_model is None else str(args.cart_model),
        fixed_contact_y=fixed_contact_y,
        base_plan=_base_plan(args.base_plan),
        tip_bound="auto" if args.tip_bound == "auto" else args.tip_bound == "on",
        arm_limits=_arm_limits(args.grip_torque_arm),
        load_changes=tuple(parse_load_change(v) for v in args.load_change or ()),
        time_scaling=_time_scaling(args.look_ahead, args.plant),
    )


def _check_initial_mass(mass: float) -> None:
    """Raise OptionError naming ``--initial-mass`` unless it is within the carts a push handles (kg)."""
    from wholebody.push.config import CART_MASS_RANGE_KG

    lo, hi = CART_MASS_RANGE_KG
    if not (math.isfinite(mass) and lo <= mass <= hi):
        raise OptionError(f"--initial-mass takes the initial mass estimate in kg within [{lo:g}, {hi:g}], got {mass:g}")


def _handle_span(cart_model: Path | None) -> tuple[float, float]:
    """Return the lateral span (m) of the handle a hand may hold: the cart file's, else the shopping cart's."""
    from wholebody.push.geometry import DEFAULT_GEOMETRY, geometry_from_cart_file

    return (DEFAULT_GEOMETRY if cart_model is None else geometry_from_cart_file(cart_model)).y_range


def _time_scaling(look_ahead: float, plant: str) -> TimeScaling | Literal["auto"]:
    """Return `PushConfig.time_scaling` for ``--look-ahead S``: "auto" for 0, the look-ahead's settings otherwise."""
    from wholebody.push.reference_clock import TimeScaling

    if not math.isfinite(look_ahead) or look_ahead < 0.0:
        raise OptionError(f"--look-ahead takes a horizon in s >= 0, got {look_ahead}")
    if look_ahead == 0.0:
        return "auto"
    if plant != "mujoco":
        raise OptionError("--look-ahead needs --plant mujoco (the kinematic plant's reference never slows)")
    return TimeScaling(horizon=look_ahead)


#: the largest |dx|, |dy| (m) of ``--initial-com``: a CoM guess farther out is not on any cart
INITIAL_COM_MAX_M = 5.0


def parse_initial_com(text: str) -> tuple[float, float]:
    """Return (dx, dy) m of ``--initial-com DX,DY``; raise OptionError naming the option otherwise."""
    parts = str(text).split(",")
    try:
        values = [float(v) for v in parts]
    except ValueError:
        values = []
    if len(values) != 2 or not all(math.isfinite(v) and abs(v) <= INITIAL_COM_MAX_M for v in values):
        raise OptionError(
            f"--initial-com takes DX,DY in m in the cart frame {{b}}, each within +-{INITIAL_COM_MAX_M:g} (e.g. "
            f"0.3,0), got {text!r}"
        )
    return values[0], values[1]


def parse_load_change(text: str) -> LoadChange:
    """Return the `LoadChange` of ``--load-change T:+M[@X,Y]`` (T s, M kg, X, Y m); raise OptionError naming the
    option otherwise."""
    from wholebody.push.load_change import LoadChange

    usage = f"--load-change takes T:+M or T:-M[@X,Y] (s, kg, m in the cart frame), got {text!r}"
    when, sep, rest = text.partition(":")
    mass, at, place = rest.partition("@")
    xy = place.split(",") if at else []
    if not sep or (at and len(xy) != 2):
        raise OptionError(usage)
    try:
        values = [float(v) for v in (when, mass, *xy)]
    except ValueError:
        raise OptionError(usage) from None
    if not all(math.isfinite(v) for v in values) or values[1] == 0.0:
        raise OptionError(usage)
    return LoadChange(values[0], values[1], (values[2], values[3]) if xy else None)


def _auto_on_off(p: argparse.ArgumentParser, flag: str, help: str) -> None:
    """Add option ``flag`` taking auto (the default), on (also the flag alone) or off."""
    p.add_argument(flag, nargs="?", const="on", default="auto", choices=("auto", "on", "off"), help=help)


def _base_plan(choice: str) -> BasePlanSettings | Literal["auto"] | None:
    """Return `PushConfig.base_plan` of ``--base-plan auto|on|off``."""
    from wholebody.push.base_settings import BasePlanSettings

    if choice == "auto":
        return "auto"
    return BasePlanSettings() if choice == "on" else None


def _arm_limits(torque_arm: float | None) -> ArmLimits:
    """Return the arms' limits with the grip's torque arm (m) of ``--grip-torque-arm`` (None: the loop's defaults)."""
    from wholebody.push.config import PUSH_ARM_LIMITS

    if torque_arm is None:
        return PUSH_ARM_LIMITS
    options.finite("--grip-torque-arm", torque_arm, positive=True, maximum=0.5, why="m of torque per N of grip")
    return PUSH_ARM_LIMITS.with_torque_arm(torque_arm)


def run(args: argparse.Namespace) -> int:
    """Run the loop; print the metrics (table or JSON) and write the requested files."""
    from cartpush.cli.estimate import _one_blas_thread

    _one_blas_thread()  # before numpy loads: the base plan's SLSQP and the loop's small matrices gain nothing from
    # a second thread, which spins waiting for a core (build_controller of Traj. 2 on the loaded 2-core machine:
    # 7.0 s CPU with the default threads, 2.8 s with one)
    config = config_from_args(args)
    if args.out is not None:
        options.writable_dir(args.out)
    if args.html is not None:
        options.writable_file(args.html, "--html")
    from cart.jsonout import dumps_strict
    from wholebody.progress import show_progress
    from wholebody.push import run_push
    from wholebody.push.cart_file import mujoco_warnings, warnings_summary
    from wholebody.push.report import what_happened

    with mujoco_warnings() as warned:  # not MuJoCo's line per warning on stderr, nor its MUJOCO_LOG.TXT in the cwd
        result = run_push(config, progress=show_progress(args.json))
    if warned:
        print(f"cartpush push: warning: {warnings_summary(warned)}", file=sys.stderr)
    written = _write_files(args, result)
    if args.json:
        out = json_report(result, written)
        if warned:
            out["mujoco_warnings"] = {"count": len(warned), "summary": warnings_summary(warned)}
        print(dumps_strict(out))
        return 0
    print_summary(result)
    print("what happened:\n" + "\n".join(f"  {line}" for line in what_happened(result)))
    for p in written:
        print(f"wrote {p}")
    if args.html is not None:
        from cartpush.cli.view import PLAYER_HINT

        print(PLAYER_HINT.format(page=args.html.name))
    return 0


def _write_files(args: argparse.Namespace, result) -> list[Path]:
    """Write the figures and the log (``--out``) and the page (``--html``); return the files written."""
    from wholebody.push.report import describe, push_log, save_figures, save_scene

    written: list[Path] = []
    if args.out is not None:
        from cart.logs import write_log

        args.out.mkdir(parents=True, exist_ok=True)
        written += save_figures({describe(result.config): result}, args.out)
        write_log(args.out / "push_log.csv", push_log(result))
        written.append(args.out / "push_log.csv")
    if args.html is not None:
        args.html.parent.mkdir(parents=True, exist_ok=True)
        written.append(save_scene(result, args.html))
    return written


def json_report(result, written: list[Path]) -> dict:
    """Return the run's ``--json`` fields: the metrics (`JSON_FIELDS` first), the plant's and the estimator's
    reports, the load changes found, the slips, what happened and the files written."""
    from wholebody.push.report import base_lateral_speed, before_loss, cart_lateral_speed, match_load_changes
    from wholebody.push.report import what_happened

    config, metrics = result.config, result.metrics.as_dict()
    out = {k: metrics[k] for k in JSON_FIELDS}
    out.update({k: v for k, v in metrics.items() if k not in out})
    if result.plant_report is not None:
        out.update(result.plant_report)
    out["estimator"] = config.estimator if config.estimation else "none"
    out.update(result.estimator_report or {})
    matched = match_load_changes(result) if config.load_changes else None
    if matched is not None:
        out["load_changes_true"] = matched
    out["cart_lateral_slip_max_m_s"] = float(abs(cart_lateral_speed(result)).max())
    out["base_lateral_speed_measured_max_m_s"] = float(abs(base_lateral_speed(result)).max())
    if result.metrics.tracking_lost_at_s is not None:
        out["before_loss"] = before_loss(result)
    out["what_happened"] = what_happened(result, matched)
    out["files"] = [str(p) for p in written]
    return out


def print_summary(result) -> None:
    """Print the run's table, what the unobservable stretches meant, and the limit verdicts (over-limit: stderr too)."""
    from wholebody.push.report import comparison_table, describe, physics_note, torque_verdict, unobservable_note

    config, metrics = result.config, result.metrics.as_dict()
    print(describe(config))
    print(comparison_table({"this run": result}))
    note = physics_note("MuJoCo plant", result)
    if note:
        print(note)
    if result.metrics.tracking_lost_at_s is not None:
        print(
            f"LOST THE CART at t = {result.metrics.tracking_lost_at_s:.2f} s: more than 25 cm from its desired place "
            "(the numbers after that describe a failed push; see the plant's report: saturation, slip, torque)"
        )
    if config.estimation:
        print(unobservable_note({"this run": result}))
        print(estimator_note(result.estimator_report or {}))
    verdict, over = torque_verdict(result)
    print(verdict)
    if over:
        print(f"cartpush push: warning: {verdict}", file=sys.stderr)
    print(saturation_note(metrics.get("saturation") or {}))
    true_mass = float(result.truth()[-1, 0])
    print(
        f"grasp error max {1000 * metrics['grasp_error_max_m']:.2f} mm; final mass {metrics['mass_final_kg']:.2f} kg "
        f"(true {true_mass:g} kg{'' if config.estimation else ', estimation off: the initial guess is kept'})"
    )


def _onset_text(change: dict) -> str:
    """Return the onsets the data cannot tell from the reported one (``t_earliest``, ``t_latest``), or that the
    onset may lie earlier than the data kept show (``censored``)."""
    lo, hi = change.get("t_earliest"), change.get("t_latest")
    if change.get("censored"):
        return f" or earlier (onsets to {hi:.2f} s fit alike; the data kept do not reach back far enough to bound it)"
    if lo is None or hi is None or hi - lo < 0.05:
        return ""
    return f" (onsets {lo:.2f}-{hi:.2f} s fit alike)"


def estimator_note(report: dict) -> str:
    """Return what the online estimator found: load changes (when, the new mass), run-off, unexcited parameters."""
    if not report:
        return "estimator: the cart paper's EKF (no load-change or run-off monitor)"
    lines = [
        f"load change at t = {c['t_change']:.2f} s{_onset_text(c)} (detected {c['t_detected']:.2f} s): mass "
        f"{c['mass_before']:.2f} -> {c['mass_after']:.2f} kg"
        for c in report.get("load_changes", [])
    ] or ["no load change detected"]
    flags = report.get("runoff_flags", [])
    kinds = sorted({f["kind"] for f in flags})
    lines.append(
        f"run-off flagged {len(flags)} time(s) ({', '.join(kinds)}): those estimates were held, not used"
        if flags
        else "no run-off: every estimate was physically plausible and fitted the data"
    )
    unexcited = report.get("unexcited") or []
    if unexcited:
        lines.append(f"not excited by this motion (kept at the prior, std says so): {', '.join(unexcited)}")
    return "\n".join(lines)


def saturation_note(saturation: dict) -> str:
    """Return one line per limit that kept the allocation from the desired wrench: from when, how long in all,
    in how many stretches (the longest), or that none did."""
    if not saturation:
        return "allocation never saturated: every desired cart wrench was produced within the limits"
    rows = sorted(saturation.items(), key=lambda kv: -kv[1]["total_s"])
    return "allocation saturated (the limit that bound, first at, total, stretches, longest):\n" + "\n".join(
        f"  {k}: from t = {v['first_s']:.2f} s, {v['total_s']:.2f} s in {v['spans']} stretch(es), longest {v['longest_s']:.2f} s"
        for k, v in rows
    )
