"""`cartpush demo`: the main job — the mobile manipulator pushes the cart with and without estimation."""

from __future__ import annotations

import argparse
from pathlib import Path

from cartpush.cli import options


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `demo` subcommand."""
    p = subparsers.add_parser(
        "demo",
        help="push the cart along Traj. 2 with and without estimation, and in MuJoCo; write a report directory",
        description=(
            "List the robot models, then run the whole loop: the Ridgeback + iiwa 14 pushes the shopping\n"
            "cart along Traj. 2 of the cart paper with the online estimate and an optimized contact point, again\n"
            "without estimation (16 kg guess for a 20 kg cart), and along Traj. 1 with robot and cart in the\n"
            "MuJoCo physics engine (fixed grip). Prints the comparison table and the physics run's plant report,\n"
            "and writes a report directory: figures (path, errors, the estimate with its band against the truth,\n"
            "the hand wrenches allocated vs measured, arm torques), the Meshcat pages scene.html (the first run)\n"
            "and scene_mujoco.html (the physics run), the run's log push_log.csv. Tracking errors are in mm, CoM\n"
            "errors in cm; the pages play when opened (pause button and legend in their bottom-left corner). A\n"
            "progress bar shows on a terminal (never with --json or when stderr is not a terminal).\n\n"
            "Example:\n  cartpush demo\n  cartpush demo --out my_report --duration 20\n  cartpush demo --robots-only --json"
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--out", type=Path, default=Path("cartpush_report"), help="report directory (default: ./cartpush_report)"
    )
    p.add_argument("--duration", type=float, default=30.0, help="seconds of each run to simulate (default 30)")
    p.add_argument(
        "--load-change",
        action="append",
        default=None,
        metavar="T:+M[@X,Y]",
        help="put M kg into the cart at T s (-M: take it out) in every run, as cartpush push --load-change",
    )
    p.add_argument("--robots-only", action="store_true", help="only list the robot models")
    p.add_argument("--json", action="store_true", help="print JSON instead of tables")
    p.set_defaults(func=run)


#: what each file of the demo's report directory shows, in the order they are listed after the run
REPORT_FILES = {
    "scene.html": "the run with estimation, animated in Meshcat: open it in a browser (works offline)",
    "scene_mujoco.html": "the MuJoCo run, animated: the hand force allocated and measured, the cart's casters",
    "estimate.png": "the mass and CoM estimates with their 1-sigma band against the truth; load changes, run-off flags",
    "tracking_estimation.png": "tracking, mass and CoM errors and the hand force over time",
    "hand_wrenches.png": "the cart wrench desired, allocated to the hands and measured (the MuJoCo run)",
    "path.png": "the paths of the cart and of the robot's base",
    "arm_torques.png": "each arm joint's torque against its limit",
    "comparison.md": "the table above, the unobservable stretches and the torque verdicts",
    "push_log.csv": "the first run's log: cartpush estimate push_log.csv, cartpush view push_log.csv",
}


def report_listing(out_dir: Path) -> list[str]:
    """Return one line per file of the report directory that `REPORT_FILES` describes (pages with their full path)."""
    lines = []
    for name, what in REPORT_FILES.items():
        path = out_dir / name
        if path.is_file():
            where = str(path.resolve()) if path.suffix == ".html" else name
            lines.append(f"  {where}: {what}")
    return lines


def robot_summary() -> list[dict]:
    """Return one dict per available robot: name, nq, nv, mass_kg, frame."""
    import pinocchio as pin

    import robots

    rows = []
    for name in robots.available():
        r = robots.load(name)
        role = "ee" if "ee" in r.frames else "handle"
        rows.append(
            {
                "name": name,
                "nq": r.model.nq,
                "nv": r.model.nv,
                "mass_kg": round(pin.computeTotalMass(r.model), 3),
                "frame": r.frames[role],
            }
        )
    return rows


def run(args: argparse.Namespace) -> int:
    """Print the robot table, run the push comparison and write the report (or JSON)."""
    from cart.jsonout import dumps_strict

    options.duration(args.duration, minimum=8.0, why="Traj. 2 needs it", rate=1000.0)
    from cartpush.cli.push import parse_load_change
    from wholebody.push.config import check_load_changes

    loads = tuple(parse_load_change(v) for v in args.load_change or ())
    check_load_changes(loads, args.duration)  # times, places on the cart, masses: before any work
    if not args.robots_only:
        options.writable_dir(args.out)
    rows = robot_summary()
    if not args.json:
        print(f"{'robot':<16}{'nq':>4}{'nv':>4}{'mass [kg]':>11}  frame")
        for r in rows:
            print(f"{r['name']:<16}{r['nq']:>4}{r['nv']:>4}{r['mass_kg']:>11.3f}  {r['frame']}")
        print()
    if args.robots_only:
        if args.json:
            print(dumps_strict({"robots": rows}))
        return 0
    import sys

    from wholebody.progress import show_progress
    from wholebody.push.cart_file import mujoco_warnings, warnings_summary
    from wholebody.push.report import run_demo

    with mujoco_warnings() as warned:  # not MuJoCo's line per warning on stderr, nor its MUJOCO_LOG.TXT in the cwd
        demo = run_demo(
            args.out,
            duration=args.duration,
            verbose=not args.json,
            progress=show_progress(args.json),
            load_changes=loads,
        )
    if warned:
        print(f"cartpush demo: warning: {warnings_summary(warned)}", file=sys.stderr)
    if not args.json:
        print("what to open:\n" + "\n".join(report_listing(demo.out_dir)))
    if args.json:
        runs = {label: _run_json(run) for label, run in demo.runs.items()}
        print(dumps_strict({"robots": rows, "runs": runs, "report_dir": str(demo.out_dir.resolve())}))
    return 0


def _run_json(run) -> dict:
    """Return a demo run's JSON: its metrics, the plant's report and, with load changes, what was found of each."""
    from wholebody.push.report import match_load_changes

    out = {**run.metrics.as_dict(), **(run.plant_report or {})}
    if run.config.load_changes:
        out["load_changes_true"] = match_load_changes(run)
    return out
