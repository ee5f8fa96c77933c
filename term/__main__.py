"""``python -m term``: the same as the ``term`` command (term/cli/main.py)."""

import sys

from term.cli.main import main

sys.exit(main())
