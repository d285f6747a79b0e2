"""The `cartpush` command line: one subcommand per module in `wholebody.commands`.

Each command module defines ``register(subparsers)`` (adds its parser and sets
``func``) and a ``run(args) -> int``. Bad input raises a project exception;
`main` turns it into one line on stderr and exit code 2.
"""
from __future__ import annotations

import argparse
import importlib
import sys
from typing import Sequence

from cart.errors import CartError
from robots.errors import RobotError
from wholebody.errors import WholeBodyError

#: Subcommand modules, in the order `cartpush --help` lists them.
COMMAND_MODULES: tuple[str, ...] = (
    "demo",
    "track",
    "reproduce",
    "estimate",
    "plan_contacts",
    "diagnose",
    "push",
    "view",
)

USER_ERRORS = (CartError, RobotError, WholeBodyError, FileNotFoundError, IsADirectoryError, PermissionError)


def build_parser() -> argparse.ArgumentParser:
    """Return the top-level argument parser with every available subcommand."""
    parser = argparse.ArgumentParser(
        prog="cartpush",
        description=(
            "Whole-body planning for mobile manipulators that push passive carts: "
            "cart dynamics and inertial-parameter EKF, contact/wrench allocation, "
            "WMRA and Ridgeback+iiwa kinematics, Meshcat scenes."
        ),
        epilog="Example: cartpush demo",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(f"wholebody.commands.{name}")
        except ModuleNotFoundError as exc:  # a command whose module is not written yet
            if exc.name == f"wholebody.commands.{name}":
                continue
            raise
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; return the process exit code (0 ok, 2 bad input)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except USER_ERRORS as exc:
        print(f"cartpush {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
