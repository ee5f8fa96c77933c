"""The ground station without a screen: the board's links, how they are kept up, where commands go, and what may
be sent. No Textual here; the app (or any other front end, or a test) composes a ``Station`` and reacts to its
events.

- Two links to one board, each a ``StationLink`` with one policy (``LinkPolicy``): the **cable** (the board's
  link: serial, or BLE alone with ``term --ble``) and the **radio** (BLE beside the cable, for the report's
  handover). A link is opened, its ``LinkSession`` started with the current stick, and when its transport dies it
  is tried again after the policy's pauses (the cable every second; BLE after 1, 2, 4, then every 8 s: a board
  out of range is not helped by a scan every second). ``reconnect_now`` tries every dead link at once.
- Routing: the sticks go to both links (whichever the board reads has the latest); commands go over the link that
  carries control: the radio once the board says STARTED, the cable otherwise (``control``).
- Send guards (``send``): leaving SAFE with the throttle up is refused here at once, with the fix; over BLE alone
  the handover cannot be asked for (the board reads it only from the cable); nothing goes to a link that is down.
  A refusal is an event with its reason, never a silent no. The joystick's fire button is PANIC (``set_stick``).

Everything that happens is an event (the dataclasses below, plus the links' own ``LinkEvent``s wrapped in
``FromLink``). Each one is applied to the model first (``Model.apply``: the one place the model changes), then
handed to ``on_event`` for the front end's reactions (a toast, exiting on ``Fatal``). The station reads the model
(mode, stick, the board's wireless state) for its guards and routing and never writes it. Time comes from the
injected ``clock``; pauses from the injected ``sleep``.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Any

from term.core.errors import EXIT_USAGE, EXIT_VERSION
from term.core.events import (
    CABLE,
    RADIO,
    Fatal,
    FromLink,
    LinkConnecting,
    LinkDown,
    LinkFailed,
    LinkUp,
    LinkWaiting,
    Note,
    NotSent,
    Requested,
    StationEvent,
    StatsSample,
    StickSet,
)
from term.core.link import LinkSession, PacketReceived, VersionMismatch
from term.core.protocol import Button, Joystick, Mode, Op
from term.input.keymap import ZERO_TRIM_STEPS
from term.input.mapping import leave_safe_refusal
from term.session.connection import Connection, ConnectionEvent, TransportFailed
from term.session.link_thread import FrontDoor, LinkThread, is_open
from term.session.model import Model
from term.session.texts import mode_name, op_text
from term.transports.base import Transport, TransportError

ZERO_AGAIN_S = 1.0  # in flight, the lift trim goes to zero only on a second press within this
RECONNECT_S = 1.0  # a dead cable is opened again this often
BLE_BACKOFF_S = (1.0, 2.0, 4.0, 8.0)  # a lost or unreachable BLE link is tried again after these pauses
# Over BLE the joystick goes out when it changes (at most 100 times a second: a mouse drag sends more events
# than that) plus a keep-alive, as the phone app did: the radio is slow.
RADIO_SESSION: dict[str, float | bool] = {"change_only": True, "keepalive": 0.5, "joystick_rate": 100.0}


# --- one link ---------------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class LinkPolicy:
    """How one link is kept: its ``LinkSession`` options and the pauses between tries (the last one repeats)."""

    session: dict[str, Any]
    backoff: tuple[float, ...] = (RECONNECT_S,)

    def pause(self, attempt: int) -> float:
        return self.backoff[min(max(attempt, 0), len(self.backoff) - 1)]


class StationLink:
    """One link of the station: a transport, its policy, and the connection while it is up."""

    def __init__(self, station: Station, role: str, transport: Transport, policy: LinkPolicy) -> None:
        self.station = station
        self.role = role
        self.transport = transport
        self.policy = policy
        self.connection: Connection | None = None
        self.last_error = ""
        self._task: asyncio.Task[None] | None = None
        self._connected_once = False

    @property
    def up(self) -> bool:
        return self.connection is not None

    async def connect(self, attempt: int = 0) -> bool:
        """Open the transport (first: finding a BLE board may take seconds, which the session must not count),
        start a session with the current stick, and the pump. False if the transport failed: a ``LinkFailed``
        for a retry (``attempt`` >= 1), only ``last_error`` for the first connection (attempt 0)."""
        st = self.station
        try:
            await self.transport.open()
            session = LinkSession(st.clock(), **self.policy.session)
            session.set_joystick(st.model.stick)  # the board hears the current stick at once
            gate = None if st.runner is None else st.runner.may_send
            conn = Connection(self.transport, session, st.clock, on_event=self._on_event, gate=gate)
            await conn.start()
        except TransportError as exc:
            message = str(exc)
            if attempt:
                st.emit(LinkFailed(self.role, message, repeated=message == self.last_error and attempt > 1))
            self.last_error = message
            return False
        self.connection = conn
        self.last_error = ""
        st.emit(LinkUp(self.role, self.transport.name, again=self._connected_once))
        self._connected_once = True
        return True

    def keep_up(self, *, immediate: bool) -> None:
        """Start (or restart: one loop per link) the loop that reconnects this link (on the link's thread)."""
        runner = self.station.runner
        if runner is not None and not runner.in_thread():
            runner.call(functools.partial(self.keep_up, immediate=immediate))
            return
        if self._task is not None and not self._task.done():
            self._task.cancel()
        self._task = asyncio.get_running_loop().create_task(self._loop(immediate), name=f"keep up {self.role}")

    async def _loop(self, immediate: bool) -> None:
        st = self.station
        attempt = 0
        while st.running and self.connection is None:
            if attempt or not immediate:
                pause = self.policy.pause(attempt - immediate)
                st.emit(LinkWaiting(self.role, self.last_error, pause))
                await st.sleep(pause)
            attempt += 1
            st.emit(LinkConnecting(self.role))
            with contextlib.suppress(TransportError):
                await self.transport.close()
            if await self.connect(attempt):
                return

    def _on_event(self, ev: ConnectionEvent) -> None:
        st = self.station
        if isinstance(ev, TransportFailed):
            self.connection = None
            self.last_error = ev.message
            st.emit(LinkDown(self.role, ev.message))
            if st.running:
                self.keep_up(immediate=False)
            return
        if st.on_packet is not None and type(ev) is PacketReceived:
            st.on_packet(self.role, ev.packet)  # here, on the link's thread: never behind the display
        st.emit(FromLink(self.role, ev))
        if type(ev) is VersionMismatch:
            st.emit(Fatal(f"board speaks protocol v{ev.board_version}, this terminal v{ev.our_version}: "
                          "update the board's firmware or the terminal", EXIT_VERSION))

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self._task
            self._task = None
        if self.connection is not None:
            conn, self.connection = self.connection, None
            await conn.stop()


# --- the station ----------------------------------------------------------------------------------------------


class Station:
    """The cable and the radio to one board, as two ``StationLink``s under one policy each."""

    def __init__(
        self,
        model: Model,
        *,
        cable: Transport | None = None,
        radio: Transport | None = None,
        cable_session: dict[str, Any] | None = None,
        radio_session: dict[str, Any] | None = None,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], Awaitable[None]] = asyncio.sleep,
        on_event: Callable[[StationEvent], None] | None = None,
        runner: LinkThread | None = None,
        on_packet: Callable[[str, Any], None] | None = None,
    ) -> None:
        """``model`` is kept up to date and read for the guards; ``cable``: the board's link (BLE alone when
        ``model.primary_ble``); ``radio``: BLE beside it, for the handover. ``runner``: the link's own thread
        (term/session/link_thread.py): the links are opened and pumped there, their events come back to the
        caller's loop (the model changes only there), and the display's watchdog gates their writes; without
        it everything runs on the caller's loop. ``on_packet(link, packet)``: every packet a link receives, as its
        session decodes it, on the link's thread (the live Foxglove server: served without waiting for the
        display, and without decoding the bytes a second time); it must neither block nor raise."""
        self.model = model
        self.runner = runner
        self._door: FrontDoor | None = None
        self.clock = clock
        self.sleep = sleep
        self.on_event = on_event
        self.on_packet = on_packet
        self.running = False
        self._fire_down = False
        self._zero_asked = -1e9  # when a lift-trim-to-zero was first asked for in flight
        cable_backoff = BLE_BACKOFF_S if model.primary_ble else (RECONNECT_S,)
        self.cable = None if cable is None else StationLink(
            self, CABLE, cable, LinkPolicy(dict(cable_session or {}), cable_backoff))
        self.radio = None if radio is None else StationLink(
            self, RADIO, radio, LinkPolicy({**RADIO_SESSION, **(radio_session or {})}, BLE_BACKOFF_S))

    # --- events -------------------------------------------------------------------------------------------

    def emit(self, ev: StationEvent) -> None:
        """Apply one event to the model, then hand it to the front end. The front end's own events (notes,
        the joystick's name) come this way too. From the link's thread the event is posted to the front end's
        loop, in order, and applied there."""
        door = self._door
        if door is not None and not door.here():
            door.post(self.emit, ev)
            return
        self.model.apply(ev, self.clock())
        if self.on_event is not None:
            self.on_event(ev)

    def post(self, fn: Callable[..., Any], *args: Any) -> None:
        """``fn(*args)`` on the front end's loop (at once when called there, or without a link thread)."""
        door = self._door
        if door is None or door.here():
            fn(*args)
        else:
            door.post(fn, *args)

    def note(self, severity: str, source: str, text: str) -> None:
        self.emit(Note(severity, source, text))

    # --- life cycle ---------------------------------------------------------------------------------------

    async def start(self) -> None:
        """Connect the cable (its failure is fatal: it was named on the command line and opened there), and
        start the radio's loop (its failures are said in the events, and retried)."""
        self.running = True
        if self.runner is not None:
            self._door = FrontDoor(asyncio.get_running_loop())
            if self.runner.on_thaw is None:
                self.runner.on_thaw = self._thawed
            if self.runner.armed is None:  # a frozen display stops the link only while the board flies
                self.runner.armed = lambda: self.model.flying
            for link in self.links:  # opened here already (term's command line checks the port before the screen)?
                if is_open(link.transport):  # closed on this loop, opened again on the link's (its reader's loop)
                    await link.transport.close()
            self.runner.start()
            self.runner.watch(asyncio.get_running_loop())
        if self.cable is not None and not await self._on_link(self.cable.connect()):
            self.emit(Fatal(self.cable.last_error, EXIT_USAGE))
            return
        if self.radio is not None:
            self.radio.keep_up(immediate=True)

    async def shutdown(self) -> None:
        self.running = False

        async def stop_links() -> None:
            for link in self.links:
                await link.stop()

        runner = self.runner
        if runner is None:
            await stop_links()
        elif runner.running:
            await runner.run(stop_links())
            runner.stop()

    async def _on_link(self, coro: Awaitable[bool]) -> bool:
        """``coro`` on the link's thread (or here without one)."""
        if self.runner is None:
            return await coro
        return await self.runner.run(coro)  # type: ignore[arg-type]

    def _thawed(self, frozen_s: float) -> None:
        """The watchdog's account, afterwards: why the board heard nothing (term's log has it too)."""
        self.note("warning", "link", f"the display was frozen for {frozen_s:.1f} s: the link stopped answering the "
                  "board on purpose (the pilot could not see), so the board's failsafe took over")

    @property
    def links(self) -> list[StationLink]:
        return [link for link in (self.cable, self.radio) if link is not None]

    def reconnect_now(self) -> None:
        """Every dead link is tried at once (and then with its usual pauses)."""
        tried = []
        for link in self.links:
            if not link.up:
                link.keep_up(immediate=True)
                tried.append(link.transport.name)
        self.note("info", "term", f"reconnecting now: {', '.join(tried)}" if tried else "every link is connected")

    def sample(self) -> None:
        """Each live link's statistics into the model (the app's render tick calls this; it is also the display's
        sign of life for the link's watchdog)."""
        if self.runner is not None:
            self.runner.alive()
        for link in self.links:
            if link.connection is not None:
                self.emit(StatsSample(link.role, link.connection.stats))

    # --- routing and guards -------------------------------------------------------------------------------

    @property
    def cable_connection(self) -> Connection | None:
        return None if self.cable is None else self.cable.connection

    @property
    def radio_connection(self) -> Connection | None:
        return None if self.radio is None else self.radio.connection

    def control(self) -> StationLink | None:
        """The link commands go over: the radio once the board flies over BLE, else the board's link; None if
        that link is down."""
        if self.radio is not None and self.radio.up and self.model.over_ble:
            return self.radio
        return self.cable if self.cable is not None and self.cable.up else None

    def refusal(self, op: Op, arg: int) -> NotSent | None:
        """Why ``(op, arg)`` must not go out now, or None."""
        model = self.model
        if op == Op.MODE:
            why = leave_safe_refusal(model.mode if model.mode is not None else Mode.SAFE, arg, model.stick)
            if why is not None:
                return NotSent(mode_name(arg), why, f"{mode_name(arg)} refused")
        if op == Op.WIRELESS and arg == 1 and model.primary_ble:
            why = "the handover is asked for over the cable: press 8 on the cable terminal"
            return NotSent("wireless handover", why, "wireless handover", "warning")
        if op == Op.TRIM_LIFT and arg <= ZERO_TRIM_STEPS and model.flying:
            # In the air the lift trim to zero cuts the lift: only a second press within ZERO_AGAIN_S does it.
            now = self.clock()
            if now - self._zero_asked > ZERO_AGAIN_S:
                self._zero_asked = now
                return NotSent("lift trim to zero", f"in flight this cuts the lift: press again within "
                               f"{ZERO_AGAIN_S:g} s to do it", "lift trim to zero", "warning")
            self._zero_asked = -1e9
        return None

    def send(self, op: Op, arg: int = 0) -> int | None:
        """Send a command over the link that carries control; its cmd_id, or None (and a NotSent) if refused."""
        refused = self.refusal(op, arg)
        if refused is not None:
            self.emit(refused)
            return None
        link = self.control()
        if link is None or link.connection is None:
            self.emit(NotSent(op_text(op, arg), "not connected"))
            return None
        self.emit(Requested(int(op), int(arg), link.role))
        return link.connection.send_command(op, arg)

    def set_stick(self, js: Joystick) -> None:
        """A new stick value: to the model and both links at once (whichever the board reads has the latest);
        the fire button's press is PANIC."""
        self.emit(StickSet(js))
        for link in self.links:
            if link.connection is not None:
                link.connection.set_joystick(js)
        fire = bool(js.buttons & Button.FIRE)
        if fire and not self._fire_down:
            self.note("error", "joystick", "fire: PANIC")
            self.send(Op.MODE, Mode.PANIC)
        self._fire_down = fire

    def set_axes(self, *, roll: int | None = None, pitch: int | None = None, yaw: int | None = None,
                 lift: int | None = None) -> None:
        """Change some axes of the stick, keep the others (the wireless screen's pad and lift slider)."""
        s = self.model.stick
        self.set_stick(Joystick(s.roll if roll is None else roll, s.pitch if pitch is None else pitch,
                                s.yaw if yaw is None else yaw, s.lift if lift is None else lift, s.buttons))
