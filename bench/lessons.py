"""Every lesson flown by its autopilot ("show me") on the simulated board, on a simulated clock: score, simulated
and wall seconds. ``Rig`` is also the harness of tests/lessons/test_lessons.py and tests/lessons/test_demo.py.

The rig is the terminal's side as the app wires it, minus the screen: term's ``Station`` (its guards and routing),
``Model`` and ``LessonDriver`` (observer, attempt, autopilot), and a ``LinkSession`` per link; and the board's side:
fcb_sim's ``Board`` in its ``World`` with the ``Instructor`` (truth out, situations in). The cable's bytes go
straight between the session and the board's UART (cut while the instructor cuts the cable); the radio's between a
second session and the board's ``WirelessLink``, as the phone's would. Truth lines go through the terminal's own
parser (``term.lessons.instructor.parse_line``). All on one 1 ms clock: a minute of flight costs a few wall seconds and
every seed is exactly repeatable. What the app does with a tick (situations to the simulator, the autopilot's
presses as the key map's actions, its stick) the rig does the same way (``perform``); the log download is
term.session.download's ``LogDownloader`` wired as the app wires it.

``python -m bench.lessons [--seed 1] [--lesson N]``; one JSON object on the last line.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from term.input.keymap import DEFAULT_KEYMAP
from term.lessons.spec import load_lessons
from tests.support.lessons_rig import Rig


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.lessons", description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--lesson", type=int, default=None, help="only this lesson")
    a = ap.parse_args(argv)
    lessons, skipped = load_lessons(actions=(b.action.name for b in DEFAULT_KEYMAP))
    for line in skipped:
        print(f"skipped: {line}", file=sys.stderr)
    if a.lesson is not None and a.lesson not in lessons:
        print(f"bench.lessons: no lesson {a.lesson}; there are {', '.join(map(str, lessons))}", file=sys.stderr)
        return 2
    rows = []
    for number, lesson in lessons.items():
        if a.lesson is not None and number != a.lesson:
            continue
        rig = Rig(a.seed)
        rig.run(0.5)
        wall = time.perf_counter()
        t0 = rig.now
        r = rig.fly_lesson(lesson)
        rows.append({"lesson": number, "score": r.score, "passed": r.passed, "failed": r.failed,
                     "sim_s": round(rig.now - t0, 1), "wall_s": round(time.perf_counter() - wall, 2),
                     "lines": r.lines})
        print(json.dumps(rows[-1]), flush=True)
    print(json.dumps({"bench": "lessons", "seed": a.seed, "rows": rows}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
