"""``python -m cartpush.cli``: the `cartpush` command line."""

import sys

from cartpush.cli.app import main

sys.exit(main())
