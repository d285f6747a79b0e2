"""The `cartpush` command line: one subcommand per module of the `cartpush.cli` package.

Each command module defines ``register(subparsers)`` (adds its parser and sets
``func``) and a ``run(args) -> int``; its heavy imports (Pinocchio, Meshcat,
the estimators) live inside ``run``. `main` imports only the module of the
command being run: ``cartpush --help`` lists the commands from `COMMANDS`
without importing any of them.

Errors: a project error (:class:`cart.errors.CartpushError`), a missing /
unreadable file or any other OSError of the run (a full disk, a read-only file
system, an I/O error: what to do is said) becomes one line on stderr,
``cartpush CMD: error: ...``, and exit code 2; any other exception is a bug: one
line naming it and exit code 1 (``--debug`` re-raises it with the traceback).
"""

from __future__ import annotations

import argparse
import errno
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


#: characters of a value that starts with a minus sign and a digit: numbers and the ``T:+M@X,Y`` of ``--load-change``
_VALUE_CHARS = frozenset("0123456789.eE+-:,@")


def _looks_negative_number(token: str) -> bool:
    """Return True for a negative number (``-1e3``, ``-inf``) or a value made of numbers that starts with a minus
    sign and a digit (``--load-change -1:+5``): no option of the CLI starts that way."""
    if len(token) < 2 or token[0] != "-" or token[1] == "-":
        return False
    if (token[1].isdigit() or token[1] == ".") and set(token) <= _VALUE_CHARS:
        return True
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


#: errno -> (what happened, what to do) for an OSError while a command runs: one line, exit code 2.
_OS_ERROR_HINTS = {
    errno.ENOSPC: ("no space left on the device", "free space or write elsewhere"),
    errno.EDQUOT: ("disk quota exceeded", "free space or write elsewhere"),
    errno.EFBIG: ("file too large for the file system", "write elsewhere"),
    errno.EROFS: ("read-only file system", "write elsewhere"),
    errno.EIO: ("input/output error", "check the disk or device, or use another file"),
    errno.EMFILE: ("too many open files", "raise the limit (ulimit -n)"),
    errno.ENFILE: ("too many open files in the system", "close other programs and retry"),
    errno.ENOMEM: ("out of memory", "reduce the duration or the log size"),
}

#: Options that name a file or directory a command writes (named in an OSError that names no file).
_OUTPUT_OPTIONS = (("html", "--html"), ("out", "--out"), ("output", "-o"))


def _os_error_line(exc: OSError, args: argparse.Namespace) -> str:
    """Return the one-line message of an OSError raised while a command ran (a full disk, a read-only file
    system, an I/O error, ...): what happened, the file (or the command's outputs when it names none), what to do."""
    if exc.errno is None:
        return _one_line(exc) or type(exc).__name__
    what, todo = _OS_ERROR_HINTS.get(exc.errno, (exc.strerror or type(exc).__name__, ""))
    if exc.filename is not None:
        where = str(exc.filename)
    else:
        outputs = [f"{flag} {getattr(args, name)}" for name, flag in _OUTPUT_OPTIONS if getattr(args, name, None)]
        where = f"writing {', '.join(outputs)}" if outputs and todo else ""
    if not todo:
        return _one_line(f"{what}: {where}" if where else what)
    return _one_line(f"{what} ({where}): {todo}" if where else f"{what}: {todo}")


def _user_error_line(exc: Exception, args: argparse.Namespace) -> str:
    """Return the one-line message of bad input: a project error, a missing / unreadable file, any OSError
    (one that names no file is blamed on the standard output when that cannot be flushed either)."""
    if isinstance(exc, OSError) and (exc.filename is not None or not isinstance(exc, USER_ERRORS)):
        if _stdout_failed() and exc.filename is None:
            exc.filename = "the standard output"
        return _os_error_line(exc, args)
    return _one_line(exc)


def _stdout_failed() -> bool:
    """Flush stdout; when it cannot be written (stdout on a full disk) drop what it holds, so that the
    interpreter's final flush does not fail again, and return True."""
    try:
        sys.stdout.flush()
    except OSError:
        _closed_stdout()
        return True
    return False


def _run(args: argparse.Namespace) -> int:
    """Run the selected command and flush its output (a closed pipe raises here, not at exit)."""
    code = int(args.func(args) or 0)
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        raise
    except OSError as exc:  # stdout redirected to a full disk: say so
        exc.filename = exc.filename or "the standard output"
        raise
    return code


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; return the process exit code (0 ok, 2 bad input, 1 internal error, 141 stdout closed).

    Bad input is a project error, a missing / unreadable file or any OSError of the run (a full disk, a
    read-only file system, an I/O error): one line naming the file and what to do, exit code 2.
    """
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
        except (*USER_ERRORS, OSError) as exc:
            print(f"cartpush {name}: error: {_user_error_line(exc, args)}", file=sys.stderr)
            return 2
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            code = _run(args)
        except BrokenPipeError:
            return _closed_stdout()
        except (*USER_ERRORS, OSError) as exc:
            print(f"cartpush {name}: error: {_user_error_line(exc, args)}", file=sys.stderr)
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
