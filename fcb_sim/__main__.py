"""``python -m fcb_sim``: the ``fcb-sim`` command (fcb_sim/cli.py), ended without the interpreter's teardown: the
atexit handlers and a flush of stdout and stderr, then out at once (as term's term/session/quick_exit.py, which
fcb_sim may not import), unless another non-daemon thread still runs. ``term --sim`` starts its board this way
(term/session/sim.py), and waits for this exit when it stops it."""

import atexit
import contextlib
import os
import sys
import threading

from fcb_sim.cli import main

code = int(main() or 0)
if any(t is not threading.main_thread() and not t.daemon and t.is_alive() for t in threading.enumerate()):
    sys.exit(code)  # the normal exit joins it
atexit._run_exitfuncs()
for stream in (sys.stdout, sys.stderr):
    with contextlib.suppress(Exception):  # (a closed pipe: nothing more can be said)
        stream.flush()
os._exit(code)
