"""``python -m term``: the same as the ``term`` command (term/cli.py)."""

import sys

from term.cli import main

sys.exit(main())
