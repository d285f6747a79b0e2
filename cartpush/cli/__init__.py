"""The `cartpush` command line (console script ``cartpush = "cartpush.cli:main"``).

`app` holds the dispatcher (`main`, `COMMANDS`); every other module of this package
is one subcommand with ``register(subparsers)`` and ``run(args) -> int``, importing
its heavy dependencies inside ``run`` (``cartpush --help`` imports none of them).


"""

from __future__ import annotations

from cartpush.cli.app import COMMAND_MODULES, COMMANDS, USER_ERRORS, build_parser, main, preprocess_argv

__all__ = ["COMMANDS", "COMMAND_MODULES", "USER_ERRORS", "build_parser", "main", "preprocess_argv"]
