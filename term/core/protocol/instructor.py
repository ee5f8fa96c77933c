"""The simulator's instructor channel's vocabulary (term --sim only): the truth fields and the situations.
"""

from __future__ import annotations

from typing import Any

from term.core.protocol.numbers import NumberError, check_number, finite, shown_text

# --- the simulator's instructor channel (term --sim only) -----------------------------------------------------
# Beside the board's link, never on it: a real board has no truth and takes no situations. fcb_sim/hosts/instructor.py
# serves it (`fcb-sim serve --instructor tcp-server:HOST:PORT`), term/lessons/instructor.py reads it; one JSON object
# per
# line each way. The simulator says {"kind": "hello", "version", "hz"}, then a {"kind": "truth", ...} line with the
# fields below INSTRUCTOR_TRUTH_HZ times a second; term sends {"do": SITUATION, ARG: value, ...} lines and gets
# {"kind": "error", "do", "why"} back for one it cannot carry out.
# The channel is the simulator's and its terminal's alone: the simulator makes a random token and prints it in the
# address (tcp-client:HOST:PORT#TOKEN, to term, its parent, on a pipe); the client's first line must be
# {"kind": "auth", "token": TOKEN}, else it gets an error line and is dropped, before any hello or truth. One client
# at a time: a second is refused. Cable and radio cuts add up to at most INSTRUCTOR_MAX_OUTAGE_S per attempt (a
# reset starts the next one).

# The simulator's starting worlds (`term --sim --scenario NAME` passes NAME to `fcb-sim serve`; fcb_sim/hosts/serve.py
# SCENARIOS describes each): both programs name them, and term offers them to shell completion.
SIM_SCENARIOS = ("bench", "breeze", "gusty", "low-battery", "no-spikes")

INSTRUCTOR_VERSION = 2
# The room term --sim flies in (the lab): walls ROOM_HALF_M from the pad on every side (a 6 m room), the ceiling
# ROOM_CEILING_M above the floor. The simulator's world meets them as it meets the floor (fcb_sim/world/physics.py); the
# room view draws them (term/lessons/room.py).
ROOM_HALF_M = 3.0
ROOM_CEILING_M = 3.0
INSTRUCTOR_AUTH = "auth"  # the first line's kind
INSTRUCTOR_TOKEN_SEP = "#"  # the address's token follows this
INSTRUCTOR_MAX_CUT_S = 60.0  # the longest one cable or radio cut may be
INSTRUCTOR_MAX_OUTAGE_S = 120.0  # cuts added up, per attempt (between resets)
INSTRUCTOR_TRUTH_HZ = 50.0
INSTRUCTOR_TRUTH: dict[str, str] = {  # field: unit and meaning (earth NED, body FRD: docs/architecture.md)
    "t": "s: the board's clock",
    "n": "m: north of the pad", "e": "m: east of the pad", "h": "m: above the floor",
    "vn": "m/s north", "ve": "m/s east", "vd": "m/s down",
    "phi": "rad: roll", "theta": "rad: pitch", "psi": "rad: heading, 0 north, positive clockwise",
    "p": "rad/s: roll rate", "q": "rad/s: pitch rate", "r": "rad/s: yaw rate",
    "on_ground": "bool: resting on its feet",
    "volts": "V: the pack under load", "soc": "0..1: the pack's state of charge",
    "landings": "touch-downs since the start", "touchdown": "m/s: the last touch-down's downward speed",
    "crashes": "impacts too fast or too tilted since the start",
    "cable": "bool: the cable carries bytes (false while the instructor cuts it)",
    "wind_n": "m/s: the mean wind towards north", "wind_e": "m/s: towards east", "gust": "m/s: gusts' std",
    "contact": "str: what the craft touches now: ground, ceiling, wall or empty",
    "touches": "count: the craft's touches of the ceiling or a wall so far (one per contact, however short)",
    "touched": "str: the last such touch's surface: ceiling, wall or empty", "touch_speed": "m/s: its speed into it",
}
INSTRUCTOR_SITUATIONS: dict[str, tuple[str, ...]] = {  # verb: its arguments (all optional)
    "reset": ("soc",),  # on the pad, nose north, fresh pack at soc, still air, no fault (on the floor in SAFE)
    "wind": ("n", "e", "gust"),  # mean wind north and east (m/s) and gusts' std (m/s)
    "battery": ("soc", "drain"),  # set the state of charge; a failing cell drains this much more per second
    "motor": ("motor", "level"),  # motor 1..4 can no longer exceed level (0..1000); level -1 frees it
    "cable": ("cuts",),  # [[after s, for s], ...] from now: the cable carries nothing then; [] clears
    "radio": ("cut",),  # out of range for this many seconds: the BLE connection drops
}
INSTRUCTOR_RANGES: dict[tuple[str, str], tuple[float, float]] = {  # (verb, argument): its closed range
    ("reset", "soc"): (0.0, 1.0),
    ("wind", "n"): (-15.0, 15.0), ("wind", "e"): (-15.0, 15.0), ("wind", "gust"): (0.0, 5.0),
    ("battery", "soc"): (0.0, 1.0), ("battery", "drain"): (0.0, 1.0),
    ("motor", "motor"): (1, 4), ("motor", "level"): (-1, 1000),  # motor commands are 0..1000 (ae)
    ("radio", "cut"): (0.1, INSTRUCTOR_MAX_CUT_S),
}
INSTRUCTOR_CUT_AFTER_MAX_S = 3600.0  # a cut starts at most this long from now
INSTRUCTOR_MAX_CUTS = 20  # cuts in one cable command


def situation_problem(cmd: Any) -> str | None:
    """Why ``cmd`` is not a situation both ends accept (its verb, its argument names, each value's type and range,
    a cable's cuts and their sum), in one line; None if it is one. The simulator checks it again where the state
    matters (a reset only on the floor in SAFE, a radio to cut, the attempt's outage so far)."""
    if not isinstance(cmd, dict):
        return "a situation is a table like {do = \"wind\", n = -1.5}"
    verb = cmd.get("do")
    allowed = INSTRUCTOR_SITUATIONS.get(verb) if isinstance(verb, str) else None
    if allowed is None:
        name = repr(verb) if verb is None or isinstance(verb, str) and len(verb) <= 20 else shown_text(verb)
        return f"unknown situation {name}; known: {', '.join(INSTRUCTOR_SITUATIONS)}"
    extra = sorted(str(k) for k in set(cmd) - {"do"} - set(allowed))
    if extra:
        return f"{verb}: unknown argument {', '.join(extra)[:80]}; known: {', '.join(allowed) or 'none'}"
    for arg in allowed:
        if arg in cmd and (verb, arg) in INSTRUCTOR_RANGES:
            lo, hi = INSTRUCTOR_RANGES[verb, arg]
            try:
                check_number(cmd[arg], arg, lo, hi, integer=verb == "motor")
            except NumberError as exc:
                return f"{verb}: {exc}"
    if verb == "cable" and "cuts" in cmd:
        return _cuts_problem(cmd["cuts"])
    return None


def _cuts_problem(cuts: Any) -> str | None:
    if not isinstance(cuts, list):
        return "cable: cuts is a list of [after s, for s]"
    if len(cuts) > INSTRUCTOR_MAX_CUTS:
        return f"cable: at most {INSTRUCTOR_MAX_CUTS} cuts at a time, got {len(cuts)}"
    total = 0.0
    for c in cuts:
        if (not isinstance(c, list | tuple) or len(c) != 2 or not all(finite(x) for x in c)
                or not (0.0 <= c[0] <= INSTRUCTOR_CUT_AFTER_MAX_S and 0.0 < c[1] <= INSTRUCTOR_MAX_CUT_S)):
            return (f"cable: each cut is [after s (0..{INSTRUCTOR_CUT_AFTER_MAX_S:g}), for s "
                    f"(0..{INSTRUCTOR_MAX_CUT_S:g})], got {shown_text(c)}")
        total += float(c[1])
    if total > INSTRUCTOR_MAX_OUTAGE_S:
        return f"cable: the cuts add up to {total:g} s of outage (at most {INSTRUCTOR_MAX_OUTAGE_S:g} s an attempt)"
    return None
