"""The board's parameters on the terminal's side: values typed or read from a file, checked against the protocol's
table (``term.core.protocol.PARAMS``), and a small client that lists, reads and sets them over a link.

- ``parse_text(spec, text)``: what a pilot types ("0.45", "ikf", "true") as the parameter's value, or a
  ``ParamError`` of one line (not a number, not a choice, out of the table's range: what is allowed);
- parameter files are TOML, one table per group: ``[ctrl] p1 = 0.45``, ``[est] attitude = "complementary"``
  (``to_toml``/``load_file``; an unknown name gets the nearest known one, a wrong type or range names the key);
  ``diff(a, b)`` lists the names whose values differ;
- ``ParamClient(connection)``: ``await list()`` (PARAM_LIST, then the ParamValue packets; a missing one is asked
  for with PARAM_GET), ``get``, ``set`` (the board's Ack or its refusal with the reason); over a ``Connection``
  without an ``on_event`` (its event queue). ``term params`` (term/cli/main.py) and the app's "apply on connect" use it.

No Textual here; the clock is the event loop's.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from term.core.link import CommandAcked, CommandFailed, PacketReceived, VersionMismatch
from term.core.protocol import (
    PARAM_BY_NAME,
    PARAM_RULES,
    PARAMS,
    Nak,
    Op,
    Param,
    ParamSpec,
    ParamValue,
    nak_text,
    param_arg,
    rule_order,
)
from term.core.schema import nearest, one_line, shown
from term.core.userfile import UserFileError, read_user_toml
from term.session.connection import Connection, TransportFailed

Value = float | str | bool
FILE_MAX_BYTES = 100_000


class ParamError(ValueError):
    """A parameter value or file that cannot be used; the message is one line."""


def spec_by_name(name: str) -> ParamSpec:
    """The table's row for ``name`` ("ctrl.p1"), or a ParamError naming the nearest one."""
    spec = PARAM_BY_NAME.get(name)
    if spec is None:
        raise ParamError(f"no parameter {name!r}{nearest(name, PARAM_BY_NAME)}; see 'term params list'")
    return spec


def check_value(spec: ParamSpec, value: Any, given: str | None = None) -> Value:
    """``value`` (from TOML or parsed text) as the parameter's value: ``ParamSpec.check``, the one strict check
    (finite, in range before scaling, on the wire's step, an exact choice); else a ParamError of one line (quoting
    ``given``, what was typed, if any)."""
    try:
        return spec.check(value, given)
    except ValueError as exc:
        hint = nearest(value, spec.choices) if spec.kind == "enum" and isinstance(value, str) else ""
        raise ParamError(one_line(f"{exc}{hint}")) from None


def parse_text(spec: ParamSpec, text: str) -> Value:
    """What a pilot typed, as the parameter's value (``ParamSpec.parse``: ASCII, strict; ParamError: one line
    saying what is allowed)."""
    try:
        return spec.parse(text)
    except ValueError as exc:
        t = text.strip(" ") if isinstance(text, str) else ""
        hint = nearest(t, spec.choices) if spec.kind == "enum" else ""
        raise ParamError(one_line(f"{exc}{hint}")) from None


def value_text(spec: ParamSpec, value: Value) -> str:
    return spec.text(value)


# --- files ------------------------------------------------------------------------------------------------------


def to_toml(values: Mapping[Param, Value], header: str = "") -> str:
    """``values`` as a parameter file: a table per group, the parameters in the table's order of names."""
    groups: dict[str, list[str]] = {}
    for p, v in sorted(values.items(), key=lambda kv: PARAMS[kv[0]].name):
        spec = PARAMS[p]
        group, key = spec.name.split(".", 1)
        if spec.kind == "enum":
            text = '"' + str(v) + '"'
        elif spec.kind == "bool":
            text = "true" if v else "false"
        elif spec.kind == "int":
            text = str(int(v))
        else:
            text = repr(float(v))
        unit = f"  # {spec.unit}" if spec.unit else ""
        groups.setdefault(group, []).append(f"{key} = {text}{unit}")
    out = [f"# {line}" for line in header.splitlines()] + ([""] if header else [])
    for group, lines in groups.items():
        out += [f"[{group}]", *lines, ""]
    return "\n".join(out)


def from_toml(data: Mapping[str, Any], where: str) -> dict[Param, Value]:
    """A parsed parameter file as values; every key checked (ParamError of one line naming ``where`` and it)."""
    values: dict[Param, Value] = {}
    for group, table in data.items():
        if not isinstance(table, Mapping):
            raise ParamError(f"{where}: {group} = {shown(table)}: parameters go in tables, e.g. [ctrl] p1 = 0.4")
        for key, value in table.items():
            name = f"{group}.{key}"
            try:
                spec = spec_by_name(name)
                values[spec.param] = check_value(spec, value)
            except ParamError as exc:
                raise ParamError(f"{where}: {exc}") from None
    return values


def load_file(path: Path) -> dict[Param, Value]:
    """A parameter file (TOML, through term/core/userfile.py: a regular file, at most ``FILE_MAX_BYTES``, UTF-8,
    bounded nesting); every problem is one ParamError."""
    try:
        data = read_user_toml(path, FILE_MAX_BYTES, "parameter file")
    except UserFileError as exc:
        raise ParamError(str(exc)) from None
    return from_toml(data, f"parameter file {path}")


def diff(ours: Mapping[Param, Value], theirs: Mapping[Param, Value]) -> list[Param]:
    """The parameters in both whose values differ (numbers compared at the wire's resolution)."""
    return sorted((p for p in ours if p in theirs and PARAMS[p].to_raw(ours[p]) != PARAMS[p].to_raw(theirs[p])),
                  key=lambda p: PARAMS[p].name)


def line(spec: ParamSpec, value: Value | None) -> str:
    """One parameter a line, as ``term params list`` prints it: name, value, unit, default (``*`` changed)."""
    shown_value = "?" if value is None else spec.text(value)
    changed = value is not None and spec.to_raw(value) != spec.to_raw(spec.default)
    return (f"{'*' if changed else ' '} {spec.name:<22} {shown_value:>14} {spec.unit:<11} "
            f"(default {spec.text(spec.default)})").rstrip()


# --- over the link ----------------------------------------------------------------------------------------------


class ParamClient:
    """List, get and set the board's parameters over one ``Connection`` (started, without ``on_event``)."""

    def __init__(self, conn: Connection, timeout: float = 3.0) -> None:
        self.conn = conn
        self.timeout = timeout

    async def _next(self, deadline: float) -> Any:
        loop = asyncio.get_running_loop()
        left = deadline - loop.time()
        if left <= 0:
            raise ParamError("no answer from the board (is it running, and on this port?)")
        try:
            ev = await asyncio.wait_for(self.conn.events.get(), left)
        except TimeoutError:
            raise ParamError("no answer from the board (is it running, and on this port?)") from None
        if isinstance(ev, TransportFailed):
            raise ParamError(ev.message)
        if isinstance(ev, VersionMismatch):
            raise ParamError(f"board speaks protocol v{ev.board_version}, this terminal v{ev.our_version}")
        return ev

    async def command(self, op: Op, arg: int = 0) -> CommandAcked | CommandFailed:
        """One command and the board's answer (the session retries it)."""
        cmd_id = self.conn.send_command(op, arg)
        deadline = asyncio.get_running_loop().time() + self.timeout
        while True:
            ev = await self._next(deadline)
            if isinstance(ev, CommandAcked | CommandFailed) and ev.cmd_id == cmd_id:
                return ev

    async def get(self, param: Param) -> int:
        ev = await self.command(Op.PARAM_GET, int(param))
        if isinstance(ev, CommandFailed):
            raise ParamError(f"{PARAMS[param].name}: {ev.reason}")
        return ev.value

    async def list(self) -> dict[Param, int]:
        """Every parameter the board has (raw values); the ones the board's listing lost are asked for alone."""
        ack = await self.command(Op.PARAM_LIST)
        if isinstance(ack, CommandFailed):
            raise ParamError(f"the board did not list its parameters: {ack.reason}")
        count = ack.value
        got: dict[int, int] = {}
        deadline = asyncio.get_running_loop().time() + self.timeout
        while len(got) < count:
            try:
                ev = await self._next(deadline)
            except ParamError:
                break  # some were lost: asked for one by one below
            if type(ev) is PacketReceived and type(ev.packet) is ParamValue:
                got[ev.packet.param] = ev.packet.value
        out = {Param(pid): raw for pid, raw in got.items() if pid in Param._value2member_map_}
        if len(got) < count:
            for p in PARAMS:
                if p not in out:
                    with contextlib.suppress(ParamError):  # a board without it
                        out[p] = await self.get(p)
        return dict(sorted(out.items(), key=lambda kv: PARAMS[kv[0]].name))

    async def set(self, param: Param, value: Value) -> tuple[bool, str]:
        """Ask the board to set ``param``; (True, the value now in force as text) or (False, the board's reason)."""
        spec = PARAMS[param]
        values: dict[Param, Value] = {param: value}
        for rule in PARAM_RULES:  # the rules between parameters, checked with the board's own values before sending
            if param in (rule.big, rule.small):
                other = rule.small if param == rule.big else rule.big
                values[other] = PARAMS[other].from_raw(await self.get(other))
                if not rule.holds(values):
                    return False, f"breaks the rule {rule.text()} ({rule.now_text(values)}): not sent"
        ev = await self.command(Op.SET_PARAM, param_arg(param, spec.to_raw(value)))
        if isinstance(ev, CommandFailed):
            return False, ev.reason
        return True, spec.text(spec.from_raw(ev.value))


def nak_reason(nak: Nak) -> str:
    return nak_text(nak)


# --- term params ------------------------------------------------------------------------------------------------

ACTIONS = ("list", "get", "set", "save", "load", "diff")


async def run_command(transport: Any, action: str, words: list[str], out: Any = print) -> int:
    """``term params ACTION ...`` against the board on ``transport`` (opened here): list | get NAME | set NAME VALUE
    | save FILE | load FILE | diff FILE. Returns the exit code (1: a value refused, a file that differs)."""
    from term.core.link import LinkSession

    request = _request(action, words)  # bad input is refused before the link is opened
    loop = asyncio.get_running_loop()
    conn = Connection(transport, LinkSession(loop.time()), loop.time)
    try:
        await conn.start()
    except Exception as exc:  # TransportError: one line
        raise ParamError(str(exc)) from None
    try:
        return await _run(ParamClient(conn), action, request, out)
    finally:
        await conn.stop()


def _request(action: str, words: list[str]) -> Any:
    need = {"list": 0, "get": 1, "set": 2, "save": 1, "load": 1, "diff": 1}
    if action not in need:
        raise ParamError(f"unknown action {action!r}{nearest(action, ACTIONS)}; one of {', '.join(ACTIONS)}")
    if len(words) != need[action]:
        usage = {"list": "list", "get": "get NAME", "set": "set NAME VALUE", "save": "save FILE",
                 "load": "load FILE", "diff": "diff FILE"}[action]
        raise ParamError(f"usage: term params {usage}")
    if action == "get":
        return spec_by_name(words[0])
    if action == "set":
        spec = spec_by_name(words[0])
        return spec, parse_text(spec, words[1])
    if action in ("load", "diff"):
        return load_file(Path(words[0]))
    if action == "save":
        path = Path(words[0])
        if path.parent and not path.parent.is_dir():
            raise ParamError(f"cannot write {path}: no directory {path.parent}")
        if path.exists() and not path.is_file():  # a FIFO would hang the write, a device take it
            raise ParamError(f"cannot write {path}: not a regular file")
        return path
    return None


async def _run(client: ParamClient, action: str, request: Any, out: Any) -> int:
    if action == "get":
        spec = request
        out(line(spec, spec.from_raw(await client.get(spec.param))))
        return 0
    if action == "set":
        spec, value = request
        ok, said = await client.set(spec.param, value)
        out(f"{spec.name} = {said}" if ok else f"{spec.name}: refused: {said}")
        return 0 if ok else 1
    board = {p: PARAMS[p].from_raw(raw) for p, raw in (await client.list()).items()}
    if action == "list":
        for p, v in board.items():
            out(line(PARAMS[p], v))
        return 0
    if action == "save":
        path = request
        try:
            path.write_text(to_toml(board, "board parameters, written by 'term params save'"), encoding="utf-8")
        except OSError as exc:
            raise ParamError(f"cannot write {path}: {exc.strerror or exc}") from None
        out(f"wrote {path}: {len(board)} parameters")
        return 0
    if action == "diff":
        differ = diff(request, board)
        for p in differ:
            spec = PARAMS[p]
            out(f"{spec.name}: board {spec.text(board[p])}, file {spec.text(request[p])}")
        missing = [PARAMS[p].name for p in request if p not in board]
        if missing:
            out(f"not on the board: {', '.join(missing)}")
        return 1 if differ or missing else 0
    refused = 0  # load
    for p in rule_order(request, board):  # (each step keeps the rules between parameters)
        v = request[p]
        if p in board and PARAMS[p].to_raw(board[p]) == PARAMS[p].to_raw(v):
            continue
        ok, said = await client.set(p, v)
        out(f"{PARAMS[p].name} = {said}" if ok else f"{PARAMS[p].name}: refused: {said}")
        refused += not ok
    out(f"{len(request) - refused} of {len(request)} parameters as in the file" + (f", {refused} refused"
                                                                                   if refused else ""))
    return 1 if refused else 0
