"""`cartpush demo`: a tour of the robot models (extended by the push loop when available)."""
from __future__ import annotations

import argparse
import json

import pinocchio as pin

import robots


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `demo` subcommand."""
    p = subparsers.add_parser(
        "demo",
        help="print the robot models (name, nq, nv, mass, end-effector/handle frame)",
        description="Print each robot model's name, nq, nv, total mass and end-effector or handle frame.\n\n"
        "Example:\n  cartpush demo\n  cartpush demo --json",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=run)


def robot_summary() -> list[dict]:
    """Return one dict per available robot: name, nq, nv, mass_kg, frame."""
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
    """Print the robot table (or JSON)."""
    rows = robot_summary()
    if args.json:
        print(json.dumps({"robots": rows}))
        return 0
    print(f"{'robot':<16}{'nq':>4}{'nv':>4}{'mass [kg]':>11}  frame")
    for r in rows:
        print(f"{r['name']:<16}{r['nq']:>4}{r['nv']:>4}{r['mass_kg']:>11.3f}  {r['frame']}")
    return 0
