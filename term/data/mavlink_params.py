"""MAVLink's parameter protocol for the endpoint (term/data/mavlink.py): the board's parameters under names of at most
16 characters (term/data/mavlink_map.py), PARAM_REQUEST_READ answered from the values term heard (or asked of the
board), PARAM_SET checked against the table and sent through the station as term's own keys are, a refusal said
(STATUSTEXT) with the value still in force (PARAM_VALUE), and every change of the board's heard by the ground
station."""

from __future__ import annotations

from typing import Any

from term.core.protocol import PARAMS, Op, Param, param_arg
from term.data.mavlink_map import PARAM_BY_MAV, PARAM_NAMES, PARAM_ORDER, param_float, param_raw


class ParamService:
    """The parameter protocol (module docstring). ``endpoint`` gives ``params`` (the board's values as heard),
    ``send``, ``text``, ``send_command`` and the codec."""

    def __init__(self, endpoint: Any) -> None:
        self.ep = endpoint

    def changed(self, pid: int, raw: int) -> None:
        """The board's value changed (a key, F11, a set of ours): the ground station hears it (as ArduPilot's do)."""
        self.ep.params[pid] = raw
        if pid in PARAM_NAMES and self.ep.heard_at is not None:
            self.ep.send([self.value(pid)])

    def complete(self) -> bool:
        return all(p in self.ep.params for p in PARAM_ORDER)

    def value(self, pid: int) -> Any:
        spec = PARAMS[Param(pid)]
        raw = self.ep.params.get(pid, spec.to_raw(spec.default))
        return self.ep._mav.param_value_encode(PARAM_NAMES[pid].encode(), param_float(spec, raw),
                                               self.ep._tele.m.MAV_PARAM_TYPE_REAL32, len(PARAM_ORDER),
                                               PARAM_ORDER.index(pid))

    def send_list(self) -> None:
        """Every parameter the board has said (all of them unless its list did not come: a ground station asks
        the missing ones by index)."""
        self.ep.send([self.value(pid) for pid in PARAM_ORDER if pid in self.ep.params])

    def read(self, msg: Any) -> None:
        if msg.param_index >= 0:
            if msg.param_index >= len(PARAM_ORDER):
                return
            pid = PARAM_ORDER[msg.param_index]
        else:
            spec = PARAM_BY_MAV.get(_name(msg.param_id))
            if spec is None:
                self.ep.text("warning", f"no parameter {_name(msg.param_id)!r} on this board")
                return
            pid = int(spec.param)
        if pid in self.ep.params:
            self.ep.send([self.value(pid)])
        else:
            self.ep._to_display(self.ep.send_command, Op.PARAM_GET, pid, ("param", pid))

    def set(self, msg: Any) -> None:
        name = _name(msg.param_id)
        spec = PARAM_BY_MAV.get(name)
        if spec is None:
            self.ep.text("error", f"no parameter {name!r} on this board")
            return
        pid = int(spec.param)
        raw, why = param_raw(spec, float(msg.param_value))
        if raw is None:
            self.refused(pid, why)
            return
        self.ep._to_display(self.ep.send_command, Op.SET_PARAM, param_arg(spec.param, raw), ("param", pid))

    def refused(self, pid: int, why: str) -> None:
        """A refused set: why (STATUSTEXT), then the value still in force (PARAM_VALUE)."""
        self.ep.text("error", f"{PARAM_NAMES[pid]} not set: {why}")
        self.ep.send([self.value(pid)])


def _name(raw: Any) -> str:
    """A param_id as text (pymavlink gives str or bytes, NUL-padded)."""
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", "replace")
    return str(raw).split("\0", 1)[0]
