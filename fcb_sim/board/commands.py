"""The board's keyboard commands: one handler per ``Op`` in a table (``COMMANDS``), like ``modes.TRANSITIONS``.

A handler takes the board's parts (``fcb_sim.board.parts.BoardParts``: what it acts on, the clock, the event emitter)
and the command's ``arg`` and returns ``(status, value, after)``: the ``Nak`` (OK when
accepted), the value the ``Ack`` carries (the new mode, trim, gain in milli-units, bytes of log, ...) and an
optional action run after the Ack is queued (packets that must follow it: a log status, the profile, a handover
stopped after its Ack went over the cable). A handler refuses with a reason, never silently.

``CommandDesk`` executes each command once: a repeat of the last command (same id, op and arg) within
``COMMAND_DEDUPE_US`` is a retry whose first answer was lost, and it is answered again without being redone.
A command that finds no room for its Ack on the link (the transmit side's answer budget, fcb_sim/board/transmit.py)
is shed: not done, not answered, counted; the terminal retries it. A handler that raises is a bug: the command
is refused (BAD_ARGUMENT) and the board keeps flying.

The parameters (``SET_PARAM``, ``PARAM_GET``, ``PARAM_LIST``) are the protocol's table (``term.core.protocol.PARAMS``)
bound to the board in ``fcb_sim.board.param_bindings``; every change, by ``SET_PARAM`` or by a gain key, is reported
after its Ack as ``EventCode.PARAM_CHANGED`` (the terminal's parameter screen and files follow the board's events).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from fcb_sim.board import param_bindings
from fcb_sim.board.console import qb_log
from fcb_sim.board.parts import BoardParts
from fcb_sim.board.scheduler import TASKS
from fcb_sim.world.constants import GAIN_PARAMS
from term.core.protocol import (
    GAIN_OPS,
    HEIGHT_KEY_STEP_MM,
    HEIGHT_SETPOINT_MAX_MM,
    HEIGHT_SETPOINT_MIN_MM,
    LEVEL_INFO,
    MOTOR_TEST_MAX_MS,
    PARAMS,
    Ack,
    Command,
    EventCode,
    Mode,
    Nak,
    Op,
    Param,
    ParamValue,
    param_arg,
    param_split,
)

GAIN_NAMES = {param: name for name, param in GAIN_PARAMS.items()}
COMMAND_DEDUPE_US = 2_000_000  # a Command repeated (same id, op, arg) within this is a retry: answered, not redone

Result = tuple[Nak, int, Callable[[], None] | None]
Handler = Callable[[BoardParts, int], Result]


def _mode(b: BoardParts, arg: int) -> Result:
    if arg == Mode.WIRELESS:
        return _wireless_start(b)
    now_s = b.now / 1e6
    b.modes.tick(now_s)
    return b.modes.request(arg, now_s), int(b.modes.mode), None


def _trim(axis: str) -> Handler:
    def handler(b: BoardParts, arg: int) -> Result:
        if axis == "lift" and b.modes.mode == Mode.HEIGHT:
            return _height_keys(b, arg)
        return Nak.OK, b.modes.adjust_trim(axis, arg), None

    return handler


def _height_keys(b: BoardParts, presses: int) -> Result:
    """In HEIGHT the lift keys move the height set point (HEIGHT_KEY_STEP_MM a press), said by an event; the lift
    trim is left as it was (leaving HEIGHT gives back the lift it was entered with). The Ack carries the trim."""
    sp = b.core.move_setpoint(presses * HEIGHT_KEY_STEP_MM / 1000, HEIGHT_SETPOINT_MIN_MM / 1000,
                              HEIGHT_SETPOINT_MAX_MM / 1000)
    return Nak.OK, b.modes.trims.lift, lambda: b.event(EventCode.HEIGHT_SETPOINT, round(sp * 1000))


def _gain(param: Param) -> Handler:
    """A gain key: ``arg`` presses of the table's step, kept inside the table's range, written by the same setter
    and guards as SET_PARAM (one writer for gains); the Ack carries the gain x 1000."""
    def handler(b: BoardParts, arg: int) -> Result:
        spec = PARAMS[param]
        value = min(spec.hi, max(spec.lo, float(param_bindings.get_value(b, param)) + arg * spec.step))
        nak, _ = param_bindings.set_raw(b, param, spec.to_raw(value))
        if nak != Nak.OK:
            return nak, 0, None
        return Nak.OK, round(float(param_bindings.get_value(b, param)) * 1000), lambda: _changed(b, param)

    return handler


def _changed(b: BoardParts, param: Param) -> None:
    b.event(EventCode.PARAM_CHANGED, param_arg(param, param_bindings.get_raw(b, param)))


def _log_start(b: BoardParts, arg: int) -> Result:
    if b.download.active:
        return Nak.LOG_BUSY, 0, None
    reason, _ = b.log.start()
    if reason == Nak.OK:
        b.log_full_reported = False
    return reason, b.log.used, None


def _log_stop(b: BoardParts, arg: int) -> Result:
    reason, _ = b.log.stop()
    return reason, b.log.used, None


def _log_reset(b: BoardParts, arg: int) -> Result:
    if b.download.active:
        return Nak.LOG_BUSY, 0, None
    return b.log.reset(b.modes.mode == Mode.SAFE), 0, None


def _log_status(b: BoardParts, arg: int) -> Result:
    return Nak.OK, b.log.used, lambda: b.tx.send_set("log_status", [b.log.status()], b.now)


def _log_download(b: BoardParts, first: int) -> Result:
    if b.modes.mode != Mode.SAFE:
        return Nak.NOT_IN_SAFE, 0, None
    reason = b.download.refusal(b.log, first)
    if reason != Nak.OK:
        return reason, b.log.n_chunks if reason == Nak.BAD_ARGUMENT else 0, None
    return Nak.OK, b.log.n_chunks, lambda: b.download.begin(first, b.log, b.send)


def _profile(b: BoardParts, arg: int) -> Result:
    return Nak.OK, len(TASKS), lambda: b.tx.send_set("profile", b.prof.packets(b.now), b.now)


def _wireless(b: BoardParts, arg: int) -> Result:
    if arg == 1:
        return _wireless_start(b)
    if arg == 0:
        return Nak.OK, 0, lambda: _wireless_stop(b)
    return Nak.BAD_ARGUMENT, 0, None


def _wireless_stop(b: BoardParts) -> None:
    b.wireless.request_stop()  # after the Ack: it still goes where the command came from
    b.wireless_events()


def _wireless_start(b: BoardParts) -> Result:
    if b.modes.mode != Mode.SAFE:
        return Nak.NOT_IN_SAFE, int(b.wireless.state), None
    reason = b.wireless.request_start()
    b.wireless_events()
    return reason, int(b.wireless.state), None


def _ack_crash(b: BoardParts, arg: int) -> Result:
    return b.modes.acknowledge_crash(), 0, None


def _set_param(b: BoardParts, arg: int) -> Result:
    pid, raw = param_split(arg)
    nak, param = param_bindings.set_raw(b, pid, raw)
    if nak == Nak.PARAM_RULE and param is not None:  # the Ack names the rule: its index in PARAM_RULES
        return nak, param_bindings.broken_rule(b, param, raw) or 0, None
    if nak != Nak.OK or param is None:
        return nak, 0 if param is None else param_bindings.get_raw(b, param), None
    return Nak.OK, param_bindings.get_raw(b, param), lambda: _changed(b, param)


def _param_get(b: BoardParts, arg: int) -> Result:
    try:
        param = Param(arg)
    except ValueError:
        return Nak.UNKNOWN_PARAM, 0, None
    return Nak.OK, param_bindings.get_raw(b, param), None


def _param_list(b: BoardParts, arg: int) -> Result:
    """Every parameter as a ParamValue packet after the Ack (whose value is how many)."""
    params = sorted(PARAMS)
    n = len(params)
    return Nak.OK, n, lambda: b.tx.send_set(
        "params", [ParamValue(int(p), param_bindings.get_raw(b, p), i, n) for i, p in enumerate(params)], b.now)


def _motor_test(b: BoardParts, arg: int) -> Result:
    """The bench motor test (fcb_sim/board/motortest.py): its own guards, on the mode machine's state."""
    nak, level = b.modes.motor_test.request(b.modes, arg, b.now / 1e6)
    if nak == Nak.OK and level:  # the C board's line, word for word (firmware/board/qb_console.c)
        qb_log(b, LEVEL_INFO, "motor test: mask %x at %d for %d ms", b.modes.motor_test.mask, level,
               MOTOR_TEST_MAX_MS)
    return nak, level, None


COMMANDS: dict[Op, Handler] = {
    Op.MODE: _mode,
    Op.TRIM_LIFT: _trim("lift"),
    Op.TRIM_ROLL: _trim("roll"),
    Op.TRIM_PITCH: _trim("pitch"),
    Op.TRIM_YAW: _trim("yaw"),
    **{Op(op): _gain(param) for op, param in GAIN_OPS.items()},  # the protocol's gain keys
    Op.LOG_START: _log_start,
    Op.LOG_STOP: _log_stop,
    Op.LOG_RESET: _log_reset,
    Op.LOG_STATUS: _log_status,
    Op.LOG_DOWNLOAD: _log_download,
    Op.PROFILE: _profile,
    Op.WIRELESS: _wireless,
    Op.SET_PARAM: _set_param,
    Op.ACK_CRASH: _ack_crash,
    Op.PARAM_GET: _param_get,
    Op.PARAM_LIST: _param_list,
    Op.MOTOR_TEST: _motor_test,
}


def execute(parts: BoardParts, cmd: Command) -> Result:
    """Run one command's handler; an unknown op is refused."""
    handler = COMMANDS.get(cmd.op)  # type: ignore[call-overload]
    if handler is None:
        return Nak.UNKNOWN_COMMAND, 0, None
    return handler(parts, cmd.arg)


class CommandDesk:
    """Answers each command once (module docstring): ``answer`` returns the Ack, the action to run after it, and
    whether the command was a retry (answered again, not redone)."""

    def __init__(self) -> None:
        self._last: tuple[int, int, int] | None = None
        self._ack: Ack | None = None
        self._at = 0
        self.shed = 0  # commands not done for want of room for their Ack

    def forget(self) -> None:
        """A terminal (re)connected: its cmd_ids start afresh, so an equal first command is not a retry."""
        self._last = self._ack = None

    def answer(self, parts: BoardParts, cmd: Command) -> tuple[Ack, Callable[[], Any] | None, bool] | None:
        """(Ack, action after it, whether it was a retry), or None when the command is shed."""
        if not parts.tx.answer_room(parts.now):
            self.shed += 1
            return None
        key = (cmd.cmd_id, cmd.op, cmd.arg)
        if key == self._last and parts.now - self._at < COMMAND_DEDUPE_US and self._ack:
            return self._ack, None, True  # a retry: the first answer was lost; do not do it twice
        after = None
        try:
            status, value, after = execute(parts, cmd)
        except Exception:  # a bug must not take the board down: refuse, and keep flying
            status, value = Nak.BAD_ARGUMENT, 0
        ack = Ack(cmd.cmd_id, cmd.op, int(status), int(value))
        self._last, self._ack, self._at = key, ack, parts.now
        return ack, after, False
