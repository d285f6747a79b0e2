"""The `cartpush` command line: one subcommand per module of the `cartpush.cli` package.

Each command module defines ``register(subparsers)`` (adds its parser and sets
``func``) and a ``run(args) -> int``; its heavy imports (Pinocchio, Meshcat,
the estimators) live inside ``run``. `main` imports only the module of the
command being run: ``cartpush --help`` lists the commands from `COMMANDS`
without importing any of them.

Errors: a project error (:class:`cart.errors.CartpushError`) or a missing /
unreadable file becomes one line on stderr, ``cartpush CMD: error: ...``, and
exit code 2; any other exception is a bug: one line naming it and exit code 1
(``--debug`` re-raises it with the traceback).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import warnings
from collections.abc import Sequence
from typing import NoReturn

from cart.errors import CartpushError

#: command -> (module in cartpush.cli, one-line help), in the order `cartpush --help` lists them.
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("demo", "push the cart along Traj. 2 with and without estimation; write a report directory"),
    "track": ("track", "track the paper's straight-line or sinusoidal end-effector path (WMRA or Ridgeback+iiwa)"),
    "reproduce": ("reproduce", "reproduce Table I of the cart paper (EKF + tracking)"),
    "estimate": ("estimate", "estimate cart mass/CoM/inertia/damping from a log (least squares or the EKF)"),
    "import": ("import_bag", "turn a ROS 1/ROS 2 bag or an MCAP file into a cart log"),
    "plan-contacts": (
        "plan_contacts",
        "choose contact points on the cart handle and allocate the end-effector wrenches (QP)",
    ),
    "diagnose": ("diagnose", "fit the cart model to a log, find significant discrepancies, name the missing effects"),
    "push": ("push", "simulate the mobile manipulator(s) pushing the cart with the EKF in the loop"),
    "view": ("view", "show a cart log, a Table I test or a robot in Meshcat"),
    "batch": ("batch", "run estimate or diagnose over many logs, locally or on a Ray cluster"),
}

#: Kept for callers of the previous API: the command modules, in help order.
COMMAND_MODULES: tuple[str, ...] = tuple(module for module, _ in COMMANDS.values())

#: Exceptions that are the user's input, not a bug: one line and exit code 2.
USER_ERRORS = (CartpushError, FileNotFoundError, IsADirectoryError, PermissionError, NotADirectoryError)

#: At most this many distinct Python warnings are echoed (one line each) after a successful command.
MAX_WARNINGS = 5


class CliParser(argparse.ArgumentParser):
    """ArgumentParser whose usage errors are one line on stderr (exit code 2), like every other bad input."""

    def error(self, message: str) -> NoReturn:
        """Print ``PROG: error: message`` on one line and exit with code 2."""
        self.exit(2, f"{self.prog}: error: {_one_line(message)} (see {self.prog} --help)\n")


def _top_parser() -> argparse.ArgumentParser:
    parser = CliParser(
        prog="cartpush",
        description=(
            "Whole-body planning for mobile manipulators that push passive carts: "
            "cart dynamics and inertial-parameter EKF, contact/wrench allocation, "
            "WMRA and Ridgeback+iiwa kinematics, Meshcat scenes.\n\n"
            "Bad input gives one line on stderr and exit code 2; an internal error exit code 1\n"
            "(--debug shows its traceback); a reader that closes the output early (| head) exit code 141."
        ),
        epilog="Example: cartpush demo\n         cartpush estimate run.csv --json\n         cartpush COMMAND --help",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--debug", action="store_true", help="re-raise internal errors with their traceback")
    return parser


def _load_module(name: str):
    """Return the command module of `name` (None when it is not written yet)."""
    module_name = COMMANDS[name][0]
    try:
        return importlib.import_module(f"cartpush.cli.{module_name}")
    except ModuleNotFoundError as exc:  # a command whose module is not written yet
        if exc.name == f"cartpush.cli.{module_name}":
            return None
        raise


def build_parser(command: str | None = "*") -> argparse.ArgumentParser:
    """Return the top-level argument parser.

    ``command``: the subcommand whose module is imported and registered in full
    (``"*"``: all of them); every other subcommand gets a placeholder parser
    that only carries its one-line help (enough for ``cartpush --help``).
    """
    parser = _top_parser()
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (_, help_text) in COMMANDS.items():
        if command == "*" or name == command:
            module = _load_module(name)
            if module is not None:
                module.register(sub)
                continue
            if command != "*":
                continue
        else:
            sub.add_parser(name, help=help_text, add_help=False)
    return parser


def _looks_negative_number(token: str) -> bool:
    if len(token) < 2 or token[0] != "-" or token[1] == "-":
        return False
    try:
        float(token)
    except ValueError:
        return False
    return True


def preprocess_argv(argv: Sequence[str]) -> tuple[list[str], bool]:
    """Return (argv for argparse, debug flag).

    ``--debug`` is accepted anywhere before ``--``. Negative numbers in scientific
    or special notation (``-1e3``, ``-inf``) are values, not options: argparse
    only recognises ``-1`` / ``-1.5`` as numbers, so these get a leading space
    (``float(" -1e3")`` is -1000), e.g. ``plan-contacts --wrench -1e3 0 0``.
    """
    out: list[str] = []
    debug = False
    rest = False
    for token in argv:
        if rest:
            out.append(token)
            continue
        if token == "--":
            rest = True
            out.append(token)
        elif token == "--debug":
            debug = True
        elif _looks_negative_number(token):
            out.append(" " + token)
        else:
            out.append(token)
    return out, debug


def _selected_command(argv: Sequence[str]) -> str | None:
    for token in argv:
        if token == "--":
            return None
        if token in COMMANDS:
            return token
        if not token.startswith("-"):
            return None  # an unknown command: argparse reports it
    return None


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


#: Python warning categories that are about library versions, not about this run: never echoed.
_QUIET = (DeprecationWarning, PendingDeprecationWarning, FutureWarning, ImportWarning, ResourceWarning)


def _echo_warnings(name: str, caught: list) -> None:
    """Print the run's Python warnings on stderr, one line each (numerical ones summarised in one line)."""
    seen: list[str] = []
    numerical: list[str] = []
    for w in caught:
        if issubclass(w.category, _QUIET):
            continue
        text = _one_line(w.message)
        if issubclass(w.category, RuntimeWarning):
            if text not in numerical:
                numerical.append(text)
        elif f"{w.category.__name__}: {text}" not in seen:
            seen.append(f"{w.category.__name__}: {text}")
    for text in seen[:MAX_WARNINGS]:
        print(f"cartpush {name}: warning: {text}", file=sys.stderr)
    if len(seen) > MAX_WARNINGS:
        print(f"cartpush {name}: warning: {len(seen) - MAX_WARNINGS} more distinct warning(s)", file=sys.stderr)
    if numerical:
        print(
            f"cartpush {name}: warning: numerical trouble during the computation ({'; '.join(numerical[:3])}"
            f"{'; ...' if len(numerical) > 3 else ''}); check the result",
            file=sys.stderr,
        )


#: Exit code of a process whose output pipe was closed by its reader (128 + SIGPIPE, as a shell reports it).
CLOSED_STDOUT = 141


def _closed_stdout() -> int:
    """Return ``CLOSED_STDOUT`` after the reader closed stdout (``cartpush estimate LOG | head -5``): stdout is
    pointed to devnull so the interpreter's final flush does not fail again (Python docs, "Note on SIGPIPE")."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    return CLOSED_STDOUT


def _run(args: argparse.Namespace) -> int:
    """Run the selected command and flush its output (a closed pipe raises here, not at exit)."""
    code = int(args.func(args) or 0)
    sys.stdout.flush()
    return code


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; return the process exit code (0 ok, 2 bad input, 1 internal error, 141 stdout closed)."""
    argv, debug = preprocess_argv(sys.argv[1:] if argv is None else list(argv))
    command = _selected_command(argv)
    parser = build_parser(command)
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        print("cartpush: error: no command given (see cartpush --help)", file=sys.stderr)
        return 2
    name = args.command
    if debug:  # internal errors propagate with their traceback; bad input stays one line
        try:
            return _run(args)
        except BrokenPipeError:
            return _closed_stdout()
        except USER_ERRORS as exc:
            print(f"cartpush {name}: error: {_one_line(exc)}", file=sys.stderr)
            return 2
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            code = _run(args)
        except BrokenPipeError:
            return _closed_stdout()
        except USER_ERRORS as exc:
            msg = str(exc)
            if isinstance(exc, OSError) and exc.filename is not None:
                msg = f"{exc.strerror or exc.__class__.__name__}: {exc.filename}"
            print(f"cartpush {name}: error: {_one_line(msg)}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print(f"cartpush {name}: interrupted", file=sys.stderr)
            return 130
        except MemoryError:
            print(f"cartpush {name}: error: out of memory (reduce the duration or the log size)", file=sys.stderr)
            return 2
        except Exception as exc:  # noqa: BLE001 - anything else is a bug: one line, exit 1
            print(
                f"cartpush {name}: internal error (bug): {type(exc).__name__}: {_one_line(exc)} "
                f"(rerun with --debug for the traceback)",
                file=sys.stderr,
            )
            return 1
    _echo_warnings(name, caught)
    return code
