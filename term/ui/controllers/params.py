"""The board's parameters in the app: when the board says Hello on its link the controller asks for the whole list
(``PARAM_LIST``: the parameter screen, the readiness panel's step counts and the gains read the board's own
values), after re-applying the pilot's saved set if the config asks for it (``[params] file`` with
``apply_on_connect = true``: each value is a ``SET_PARAM``; the board's refusals appear in the events list and on
the parameter screen). The parameter screen's requests (``SetParam``, ``ReloadParams``) become commands here.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from term.core.events import CABLE, FromLink
from term.core.link import PacketReceived
from term.core.protocol import PARAMS, Hello, Op, Param, param_arg, rule_order
from term.session.config import Config
from term.session.param_client import ParamError, load_file
from term.session.station import Station

Send = Callable[[Op, int], "int | None"]


class ParamsController:
    """The parameters' exchange with the board (module docstring); ``send`` is the app's command path."""

    def __init__(self, config: Config, station: Station, send: Send, *, replay: bool = False) -> None:
        """``replay``: a recording plays (its Hello asks nothing: there is no board)."""
        self.config = config
        self.station = station
        self.send = send
        self.replay = replay

    def on_station_event(self, ev: Any) -> None:
        """A station event: the board's Hello on its link starts the parameters' exchange."""
        if type(ev) is FromLink and ev.link == CABLE and type(ev.event) is PacketReceived:
            if type(ev.event.packet) is Hello:
                self.board_said_hello()

    def board_said_hello(self) -> None:
        cfg = self.config
        if cfg.params_apply and cfg.params_file is not None:
            try:
                values = load_file(cfg.params_file)
            except ParamError as exc:
                self.station.note("error", "params", f"{exc}: not applied")
            else:
                now = {s.param: self.station.model.params[s.name] for s in PARAMS.values()
                       if s.name in self.station.model.params}
                for p in rule_order(values, now):  # (each step keeps the rules between parameters)
                    self.send(Op.SET_PARAM, param_arg(p, PARAMS[p].to_raw(values[p])))
                self.station.note("info", "params", f"{len(values)} parameters from {cfg.params_file} sent to the "
                                  "board (apply_on_connect); refusals follow")
        link = self.station.control()
        if not self.replay and link is not None and link.connection is not None:
            cmd = self.send(Op.PARAM_LIST, 0)  # the terminal's own request, not the pilot's: its failure is no error
            if cmd is not None:
                self.station.model.own.add(cmd)

    def set_param(self, param: Param, value: float | str | bool) -> None:
        self.send(Op.SET_PARAM, param_arg(param, PARAMS[param].to_raw(value)))

    def reload(self) -> None:
        self.send(Op.PARAM_LIST, 0)
