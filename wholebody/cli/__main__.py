"""``python -m wholebody.cli``: the `cartpush` command line."""

import sys

from wholebody.cli.app import main

sys.exit(main())
