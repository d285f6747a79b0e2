"""The `cartpush` command line (console script ``cartpush = "wholebody.cli:main"``).

`app` holds the dispatcher (`main`, `COMMANDS`); every other module of this package
is one subcommand with ``register(subparsers)`` and ``run(args) -> int``, importing
its heavy dependencies inside ``run`` (``cartpush --help`` imports none of them).
Only the commands that run studies (`reproduce`, `track`, `view --scenario`) import
`studies`, lazily.
"""

from __future__ import annotations

from wholebody.cli.app import COMMAND_MODULES, COMMANDS, USER_ERRORS, build_parser, main, preprocess_argv

__all__ = ["COMMANDS", "COMMAND_MODULES", "USER_ERRORS", "build_parser", "main", "preprocess_argv"]
