"""``python -m fcb_sim``: the same as the ``fcb-sim`` command (fcb_sim/cli.py)."""

import sys

from fcb_sim.cli import main

sys.exit(main())
