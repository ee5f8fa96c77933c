"""``python -m term``: the same as the ``term`` command (term/cli/main.py)."""

from term.cli.main import run

run()
