"""`cartpush plan-contacts`: where each arm should hold the handle, and with which wrench."""

from __future__ import annotations

import argparse

from cartpush.cli import options

#: The default handle length (m), as `wholebody.contacts.handle.HANDLE_WIDTH` (kept here so --help imports nothing heavy).
HANDLE_WIDTH = 0.5


#: Why `--robot` does not apply here (one line, exit 2).
ROBOT_NOT_TAKEN = (
    "--robot {robot}: plan-contacts plans for hands bounded by --max-force and --max-torque, not for a robot: "
    "a robot's joint torque limits depend on the posture its arms hold the handle in; "
    "`cartpush push --robot {robot}` plans its contacts with every joint torque bounded"
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `plan-contacts` subcommand."""
    p = subparsers.add_parser(
        "plan-contacts",
        help="choose contact points on the cart handle and allocate the end-effector wrenches (QP)",
        description=(
            "Find the globally minimum-effort contact points on the handle for a cart wrench\n"
            "Gamma_MM = (fx, fy, tau) in the cart frame {b} (tau about the fixed-axle midpoint),\n"
            "and each end effector's wrench [fx, fy, fz, tx, ty, tz] in its contact frame.\n\n"
            "Example:\n  cartpush plan-contacts --wrench 40 0 -2 --arms 2 --json\n"
            "  cartpush plan-contacts --wrench -1e3 0 0   (negative numbers are values, also in e-notation)"
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--wrench",
        nargs=3,
        type=float,
        required=True,
        metavar=("FX", "FY", "TAU"),
        help="cart wrench in {b}: forces in N, torque in N m",
    )
    p.add_argument("--arms", type=int, default=1, help="number of arms (default 1)")
    p.add_argument(
        "--robot",
        default=None,
        metavar="NAME|PROFILE.toml",
        help="not taken: the plan is for hands bounded by --max-force/--max-torque; a robot's joint torque limits "
        "depend on its posture and are honoured by `cartpush push --robot` (exit 2 naming why)",
    )
    p.add_argument(
        "--handle-width", type=float, default=HANDLE_WIDTH, help=f"handle length in m (default {HANDLE_WIDTH})"
    )
    p.add_argument("--min-spacing", type=float, default=0.2, help="minimum distance between arms in m (default 0.2)")
    p.add_argument("--grip-force", type=float, default=100.0, help="gripper force in N, 20..235 (default 100)")
    p.add_argument("--max-force", type=float, default=150.0, help="per-arm force bound per axis in N (default 150)")
    p.add_argument("--max-torque", type=float, default=20.0, help="per-arm torque bound per axis in N m (default 20)")
    p.add_argument(
        "--motion-only", action="store_true", help="match only fx and tau: the wheels absorb the lateral force"
    )
    p.add_argument("--solver", default="proxqp", help="qpsolvers backend (default proxqp)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Plan the contacts and print them (table or JSON)."""
    _check_options(args)
    from cart.jsonout import dumps_strict

    plan = _plan_explained(args)
    contacts = _contact_rows(plan, args.arms)
    if args.json:
        print(
            dumps_strict(
                {
                    "contacts": contacts,
                    "residual": plan.allocation.residual,
                    "effort": plan.effort,
                    "gamma_achieved": [float(v) for v in plan.allocation.gamma_achieved],
                }
            )
        )
        return 0
    _print_table(args, plan, contacts)
    return 0


def _check_options(args: argparse.Namespace) -> None:
    """Raise `options.OptionError` for a non-finite or out-of-range option."""
    for k, v in zip(("FX", "FY", "TAU"), args.wrench):
        options.finite(f"--wrench {k}", v, maximum=1e6, minimum=-1e6)
    options.finite("--handle-width", args.handle_width, positive=True, maximum=100.0)
    options.finite("--min-spacing", args.min_spacing, nonnegative=True, maximum=100.0)
    options.finite("--grip-force", args.grip_force, positive=True, maximum=1e6)
    options.finite("--max-force", args.max_force, positive=True, maximum=1e7)
    options.finite("--max-torque", args.max_torque, positive=True, maximum=1e7)
    if not 1 <= args.arms <= 8:
        raise options.OptionError(f"--arms must be between 1 and 8, got {args.arms}")
    if args.robot is not None:
        raise options.OptionError(ROBOT_NOT_TAKEN.format(robot=args.robot))


def _plan(args: argparse.Namespace):
    """Return the `ContactPlan` of the options (`optimal_contact_points`)."""
    from wholebody.contacts.allocation import ArmLimits, GraspModel
    from wholebody.contacts.handle import HandleSegment
    from wholebody.contacts.placement import optimal_contact_points

    handle = HandleSegment.default(width=args.handle_width)
    limits = ArmLimits(
        max_force=args.max_force, max_torque=args.max_torque, grasp=GraspModel(grip_force=args.grip_force)
    )
    return optimal_contact_points(
        args.wrench,
        handle,
        n_arms=args.arms,
        min_spacing=args.min_spacing,
        limits=limits,
        only_motion_directions=args.motion_only,
        solver=args.solver,
    )


#: Why each kind of limit binds, in the options' words (label fragment -> reason).
LIMIT_REASONS = (
    ("grip pull", "a hand pulls the handle back only as hard as its grip holds it (--grip-force)"),
    ("grip torque", "the grip slips before it passes that torque to the handle (--grip-force)"),
    ("force bound", "each hand pushes at most --max-force per axis"),
    ("torque bound", "each hand twists at most --max-torque per axis"),
    ("torque limit", "an arm joint's torque limit (its URDF effort) binds"),
)


def _plan_explained(args: argparse.Namespace):
    """Return `_plan(args)`; an unachievable wrench raises `InfeasibleWrenchError` saying which limit binds and why."""
    from wholebody.errors import InfeasibleWrenchError

    try:
        return _plan(args)
    except InfeasibleWrenchError as exc:
        raise InfeasibleWrenchError(_infeasible_message(args, exc), exc.binding, exc.closest) from exc


def _infeasible_message(args: argparse.Namespace, exc) -> str:
    """Return one line: the requested wrench, the binding limit, the reason, the closest achievable wrench (rounded)."""
    fx, fy, tau = (_num(v, 2) for v in args.wrench)
    reason = next((why for key, why in LIMIT_REASONS if key in exc.binding), "")
    closest = ""
    if exc.closest is not None:
        cx, cy, ct = (_num(v, 2) for v in exc.closest)
        closest = f"; closest achievable with {args.arms} arm(s): fx {cx} N, fy {cy} N, tau {ct} N m"
    why = f" ({reason})" if reason else ""
    return (
        f"cart wrench fx {fx} N, fy {fy} N, tau {tau} N m is not achievable: {exc.binding or 'a limit'} binds{why}"
        f"{closest}"
    )


def _contact_rows(plan, n_arms: int) -> list[dict]:
    """Return one dict per arm: its index, contact point in {b} and wrench in {a}, rounded to 6 decimals."""
    return [
        {
            "arm": i,
            "point_b": [round(float(v), 6) for v in plan.points_b[i]],
            "wrench_ee": [round(float(v), 6) for v in plan.allocation.wrenches_ee[i]],
        }
        for i in range(n_arms)
    ]


def _print_table(args: argparse.Namespace, plan, contacts: list[dict]) -> None:
    """Print the contacts as a table, then the achieved cart wrench and the effort."""
    print("contact points in the cart frame {b} (origin: fixed-axle midpoint, x forward, y left, z up);")
    print("each hand's wrench in its contact frame {a} (axes of {b}, origin at the contact point)")
    heads = ("arm", "x [m]", "y [m]", "z [m]", "fx [N]", "fy [N]", "fz [N]", "tx [N m]", "ty [N m]", "tz [N m]")
    rows = [
        [str(c["arm"])] + [_num(v, 3) for v in c["point_b"]] + [_num(v, 2) for v in c["wrench_ee"]] for c in contacts
    ]
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(heads)]
    print("  ".join(h.rjust(w) for h, w in zip(heads, widths)))
    for r in rows:
        print("  ".join(v.rjust(w) for v, w in zip(r, widths)))
    fx, fy, tau = (float(v) for v in plan.allocation.gamma_achieved)
    residual = plan.allocation.residual
    match = "exactly" if residual < 5e-3 else f"within {residual:.2f} (|requested - achieved|, N and N m)"
    print(
        f"cart wrench in {{b}}: achieved fx {_num(fx, 2)} N, fy {_num(fy, 2)} N, tau {_num(tau, 2)} N m "
        f"(requested {_num(args.wrench[0], 2)} N, {_num(args.wrench[1], 2)} N, {_num(args.wrench[2], 2)} N m: "
        f"met {match})"
    )
    print(f"effort {plan.effort:.4g} (sum over arms of |f|^2 [N^2] + |tau|^2 [(N m)^2], unit weights)")


def _num(value: float, decimals: int) -> str:
    """Return `value` with `decimals` decimals, printing 0 for values that round to zero (never -0.00)."""
    text = f"{float(value):.{decimals}f}"
    return f"{0.0:.{decimals}f}" if float(text) == 0.0 else text
