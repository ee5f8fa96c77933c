"""The Textual app: owns the model, composes the panels, routes keys and the joystick to the link.

- Link events arrive on the connection's tasks (the same event loop) and only update the model; heartbeat ACKs
  are written by the connection itself, never waiting for the screen.
- The screen is redrawn from the model at a steady rate (``render_hz``), never per byte.
- Two links at once (``term --sim``, ``term --serial P --ble A``): the cable and the radio (BLE), each a
  ``Connection`` with its own session. Packets from either update the one model (it is one board); the sticks go
  to both; commands go over the link that carries control: the radio once the board says STARTED (the report's
  handover, key 8), the cable otherwise. A lost radio hands control back to the cable at once, and is tried
  again with a growing pause (1, 2, 4, 8 s); the palette's "reconnect now" tries every dead link at once.
- Pilot keys are priority bindings generated from the key map: they work on every screen (help and plots
  included) except while a text input (the command palette) has focus. A key press goes out at once: the command
  is queued in the session and the connection's timer task is woken to write it.
"""

from __future__ import annotations

import asyncio
import contextlib
import sys
import time
from collections.abc import Callable, Iterable
from datetime import datetime
from pathlib import Path

from textual.app import App, ComposeResult, SystemCommand
from textual.containers import Horizontal, Vertical
from textual.screen import Screen
from textual.widgets import Footer, Input

from term.cli import EXIT_USAGE, EXIT_VERSION
from term.config import Config
from term.connection import Connection, TransportFailed
from term.input.joystick import JoystickPoller
from term.input.keymap import Action, KeyBinding, action_by_name, pretty_key
from term.input.mapping import NEUTRAL, leave_safe_refusal
from term.link import CommandFailed, LinkSession, VersionMismatch
from term.logfile import LogDownload, log_filename, write_csv
from term.model import Model, mode_name, op_text
from term.protocol import Button, Joystick, LogState, Mode, Op, WirelessState
from term.transports.base import Transport, TransportError
from term.widgets.base import ModelView
from term.widgets.battery import BatteryGauge
from term.widgets.controls import ControlsPanel
from term.widgets.dirprompt import DirectoryPrompt
from term.widgets.download import DownloadPanel
from term.widgets.events import EventsList
from term.widgets.help import HelpScreen
from term.widgets.horizon import HeadingTape, Horizon
from term.widgets.link import LinkPanel
from term.widgets.mode import ModeBanner
from term.widgets.motors import MotorBars
from term.widgets.plots import LivePlot
from term.widgets.pressure import PressureIndicator
from term.widgets.profile import ProfileTable
from term.widgets.rates import RateGauges
from term.widgets.wireless import WirelessScreen

DOWNLOAD_STALL_S = 1.0  # no chunk for this long: resume from the first missing one
DOWNLOAD_RESUMES = 20
RECONNECT_S = 1.0  # a dead transport is opened again this often
DOWNLOAD_GAP_S = 0.2  # the board finished but chunks are missing: ask again from the first gap this soon
RADIO_BACKOFF_S = (1.0, 2.0, 4.0, 8.0)  # a lost or unreachable radio is tried again after these pauses
# Over BLE the joystick goes out when it changes (at most 100 times a second: a mouse drag sends more events
# than that) plus a keep-alive, as the phone app did: the radio is slow.
RADIO_SESSION: dict[str, float | bool] = {"change_only": True, "keepalive": 0.5, "joystick_rate": 100.0}


def _panel(widget: ModelView, title: str, wid: str) -> ModelView:
    widget.border_title = title
    widget.id = wid
    return widget


class FlightScreen(Screen[None]):
    """The main screen: everything a pilot needs at a glance."""

    def compose(self) -> ComposeResult:
        yield ModeBanner(id="mode")
        with Horizontal(id="top"):
            with Vertical(id="attitude") as v:
                v.border_title = "attitude · heading"
                yield Horizon(id="horizon")
                yield HeadingTape(id="heading")
            with Vertical(id="gauges"):
                yield _panel(RateGauges(), "rates", "rates")
                yield _panel(MotorBars(), "motors", "motors")
            with Vertical(id="power"):
                yield _panel(BatteryGauge(), "battery", "battery")
                yield _panel(PressureIndicator(), "pressure · height", "pressure")
        with Horizontal(id="middle"):
            yield _panel(ControlsPanel(), "sticks · trims · gains", "controls")
            yield _panel(LinkPanel(), "link", "link")
        yield DownloadPanel(id="download")
        yield _panel(EventsList(), "events · errors", "events")
        yield Footer()


class PlotsScreen(Screen[None]):
    def __init__(self, series: tuple[str, ...], window: float) -> None:
        super().__init__()
        self.series = series
        self.window = window

    def compose(self) -> ComposeResult:
        yield ModeBanner(id="mode")
        from term.config import PLOT_SERIES

        by_unit: dict[str, list[str]] = {}
        for s in self.series:
            by_unit.setdefault(PLOT_SERIES[s][1], []).append(s)
        with Vertical(id="plots"):
            for i, group in enumerate(by_unit.values()):
                yield LivePlot(tuple(group), self.window, id=f"plot{i}", classes="plot")
        yield _panel(EventsList(), "events · errors", "events-small")
        yield Footer()


class ProfileScreen(Screen[None]):
    def compose(self) -> ComposeResult:
        yield ModeBanner(id="mode")
        yield _panel(ProfileTable(), "profile", "profile")
        yield _panel(EventsList(), "events · errors", "events-small")
        yield Footer()


class TermApp(App[int]):
    CSS_PATH = str(Path(__file__).with_name("app.tcss"))
    TITLE = "quadrupel term"
    ENABLE_COMMAND_PALETTE = True

    def __init__(
        self,
        transport: Transport | None = None,
        *,
        config: Config | None = None,
        joystick: bool = True,
        clock: Callable[[], float] = time.monotonic,
        render_hz: float = 12.0,
        joystick_hz: float = 100.0,
        session_options: dict[str, float | bool] | None = None,
        log_directory: Path | None = None,
        radio: Transport | None = None,
        primary_ble: bool = False,
        start_screen: str = "flight",
    ) -> None:
        """``transport``: the board's link (the cable, or BLE with ``primary_ble``); ``radio``: a BLE transport
        to the same board beside the cable, for the handover; ``start_screen``: "flight" or "wireless"."""
        super().__init__()
        self.config = config or Config()
        self.keymap: tuple[KeyBinding, ...] = self.config.keymap
        self.clock = clock
        self.render_hz = render_hz
        self.joystick_hz = joystick_hz
        self.model = Model(start=clock())
        self.model.link_name = transport.name if transport else ""
        self.transport = transport
        self.session_options = session_options or {}
        self.connection: Connection | None = None
        self.radio = radio
        self.radio_connection: Connection | None = None
        self.model.radio_name = radio.name if radio is not None else ""
        self.model.primary_ble = primary_ble
        self.start_screen = start_screen
        self._reconnect_radio_error = ""
        self.poller: JoystickPoller | None = None
        self._want_joystick = joystick
        self.log_directory = log_directory or self.config.log_directory
        self.exit_message: str | None = None
        self._resumes = 0
        self._resumed_at = -1e9
        self._reconnect_error = ""
        self._fire_down = False
        for b in self.keymap:
            self._bindings.bind(
                ",".join(b.keys), f"pilot('{b.action.name}')", b.action.description,
                show=b.action.name in ("help", "show_plots", "show_flight", "show_profile", "show_wireless",
                                       "log_download"),
                key_display=" ".join(pretty_key(k) for k in b.keys), priority=True,
            )

    # --- life cycle ---------------------------------------------------------------------------------------

    def get_default_screen(self) -> Screen[None]:
        return FlightScreen(id="flight")

    async def on_mount(self) -> None:
        # Plots are drawn on a worker thread and serial bytes arrive on one: hand the GIL back to the event loop
        # within 1 ms (Python's default is 5 ms), so heartbeat answers and key presses never wait behind them.
        sys.setswitchinterval(0.001)
        self.install_screen(PlotsScreen(self.config.plot_series, self.config.plot_window), "plots")
        self.install_screen(ProfileScreen(), "profile")
        self.install_screen(WirelessScreen(), "wireless")
        self.set_interval(1.0 / self.render_hz, self.render_now)
        if self.transport is not None:
            await self._connect(self.transport)
        if self.radio is not None:
            self.run_worker(self._radio_loop(), exclusive=True, group="radio")
        if self.start_screen != "flight":
            self._show(self.start_screen)
        if self._want_joystick:
            self.call_after_refresh(self._start_joystick)
        self.render_now()

    async def _connect(self, transport: Transport, *, retrying: bool = False) -> bool:
        now = self.clock()
        from term.config import JOYSTICK_POLICIES

        opts = {"link_timeout": self.config.link_timeout, **JOYSTICK_POLICIES[self.config.joystick_policy],
                **self.session_options}
        session = LinkSession(now, **opts)  # type: ignore[arg-type]
        session.set_joystick(self.model.stick if retrying else NEUTRAL)  # the board hears from us at once
        conn = Connection(transport, session, self.clock, on_event=self._on_link_event)
        try:
            await conn.start()
        except TransportError as exc:
            if not retrying:
                self._fatal(str(exc), EXIT_USAGE)
            elif str(exc) != self._reconnect_error:
                self._reconnect_error = str(exc)
                self.model.note(self.clock(), "warning", "link", f"reconnecting: {exc}")
            return False
        self.connection = conn
        self.model.note(self.clock(), "info", "link", f"{'re' if retrying else ''}connected to {transport.name}")
        return True

    async def _reconnect(self, immediate: bool = False) -> None:
        """The transport died (a cable pulled out): try again every second until it is back or we quit; a BLE
        link with a growing pause (a board out of range is not helped by a scan every second)."""
        attempt = 0
        while self.is_running and self.transport is not None and self.connection is None:
            if not immediate or attempt:
                await asyncio.sleep(self._backoff(attempt - immediate) if self.model.primary_ble else RECONNECT_S)
            attempt += 1
            with contextlib.suppress(TransportError):
                await self.transport.close()
            if await self._connect(self.transport, retrying=True):
                return

    @staticmethod
    def _backoff(attempt: int) -> float:
        return RADIO_BACKOFF_S[min(attempt, len(RADIO_BACKOFF_S) - 1)]

    # --- the radio: a second link, over BLE, for the handover -----------------------------------------------

    async def _radio_loop(self, immediate: bool = True) -> None:
        """Connect the radio (at once, or after a pause when it was just lost); while it cannot be reached, try
        again after 1, 2, 4, then every 8 s. The palette's "reconnect now" starts a new loop (this one is
        cancelled: one loop per link)."""
        attempt = 0
        model = self.model
        while self.is_running and self.radio is not None and self.radio_connection is None:
            if attempt or not immediate:
                pause = self._backoff(attempt - immediate)
                model.radio_note = f"down: {self._reconnect_radio_error or 'lost'}; next try in {pause:.0f} s"
                model.version += 1
                await asyncio.sleep(pause)
            attempt += 1
            model.radio_note = "connecting…"
            model.version += 1
            with contextlib.suppress(TransportError):
                await self.radio.close()
            if await self._connect_radio(self.radio, attempt):
                return

    async def _connect_radio(self, transport: Transport, attempt: int) -> bool:
        try:
            await transport.open()  # first: finding the board may take seconds, which the session must not count
            session = LinkSession(self.clock(), **{"link_timeout": self.config.link_timeout, **RADIO_SESSION})  # type: ignore[arg-type]
            session.set_joystick(self.model.stick)
            conn = Connection(transport, session, self.clock, on_event=self._on_radio_event)
            await conn.start()
        except TransportError as exc:
            if str(exc) != self._reconnect_radio_error or attempt == 1:
                self.model.note(self.clock(), "warning", "ble", f"radio not connected: {exc}")
            self._reconnect_radio_error = str(exc)
            return False
        self.radio_connection = conn
        self._reconnect_radio_error = ""
        self.model.radio_up = True
        self.model.radio_note = ""
        self.model.note(self.clock(), "info", "ble", f"radio connected: {transport.name} (key 8 in SAFE hands "
                        "control over to it)")
        return True

    def _on_radio_event(self, ev: object) -> None:
        now = self.clock()
        model = self.model
        if type(ev) is TransportFailed:
            was_flying_ble = model.over_ble
            self.radio_connection = None
            model.radio_up = False
            model.radio_lost = False
            self._reconnect_radio_error = ev.message  # type: ignore[attr-defined]
            model.note(now, "error", "ble", f"BLE LOST: {ev.message}")  # type: ignore[attr-defined]
            if model.wireless != WirelessState.DISCONNECTED:
                # The board drops the handover with the connection (report Figure 12): control is the cable's.
                model.wireless = int(WirelessState.DISCONNECTED)
                model.note(now, "error", "ble", "control back on the cable: the board goes DISCONNECTED"
                           + (" and PANICs (it was flying over BLE)" if was_flying_ble and model.flying else ""))
            self.run_worker(self._radio_loop(immediate=False), exclusive=True, group="radio")
            return
        model.radio_event(ev, now)
        if type(ev) is VersionMismatch:
            self._version_mismatch(ev)

    def control_connection(self) -> Connection | None:
        """The connection commands go over: the radio once the board flies over BLE, else the board's link."""
        if self.radio_connection is not None and self.model.over_ble:
            return self.radio_connection
        return self.connection

    def reconnect_now(self) -> None:
        """The palette's "reconnect now": every dead link is tried at once (and then with the usual pauses)."""
        tried = []
        if self.transport is not None and self.connection is None:
            self.run_worker(self._reconnect(immediate=True), exclusive=True, group="reconnect")
            tried.append(self.transport.name)
        if self.radio is not None and self.radio_connection is None:
            self.run_worker(self._radio_loop(), exclusive=True, group="radio")
            tried.append(self.radio.name)
        self.model.note(self.clock(), "info", "term",
                        f"reconnecting now: {', '.join(tried)}" if tried else "every link is connected")

    def _start_joystick(self) -> None:
        poller = JoystickPoller(self.config.joystick_mappings, resolution=self.config.joystick_resolution,
                                forced=_forced(self.config))
        for msg in poller.start():
            self.model.note(self.clock(), "info", "joystick", msg)
        self.poller = poller
        if poller.name:
            self.model.joystick_name, self.model.joystick_mapping = poller.name, poller.mapping.name
        self.set_interval(1.0 / self.joystick_hz, self.poll_joystick)

    async def on_unmount(self) -> None:
        await self.shutdown()

    async def shutdown(self) -> None:
        if self.connection is not None:
            await self.connection.stop()
            self.connection = None
        if self.radio_connection is not None:
            await self.radio_connection.stop()
            self.radio_connection = None
        if self.poller is not None:
            self.poller.close()
            self.poller = None

    def _version_mismatch(self, ev: VersionMismatch) -> None:
        self._fatal(f"board speaks protocol v{ev.board_version}, this terminal v{ev.our_version}: "
                    "update the board's firmware or the terminal", EXIT_VERSION)

    def _fatal(self, message: str, code: int) -> None:
        self.exit_message = message
        self.exit(code, return_code=code)

    # --- link events (on the connection's tasks) ----------------------------------------------------------

    def _on_link_event(self, ev: object) -> None:
        now = self.clock()
        if type(ev) is TransportFailed:
            self.model.link_lost = True
            self.model.version += 1
            self.model.note(now, "error", "link", f"LINK LOST: {ev.message}")  # type: ignore[attr-defined]
            if self.model.primary_ble and self.model.flying:
                self.model.note(now, "error", "link", "the board PANICs: it was flying over this BLE link")
            self.connection = None
            self._reconnect_error = ""
            self.run_worker(self._reconnect(), exclusive=True, group="reconnect")
            return
        self.model.apply(ev, now)
        if type(ev) is VersionMismatch:
            self._version_mismatch(ev)
        elif type(ev) is CommandFailed and ev.op in (Op.LOG_DOWNLOAD,) and self.model.download is not None:
            self.model.download = None
            self.model.download_note = f"log download stopped: {ev.reason}"

    # --- rendering ----------------------------------------------------------------------------------------

    def render_now(self) -> None:
        now = self.clock()
        model = self.model
        if self.connection is not None:
            model.set_link_stats(self.connection.stats, now)
        if self.radio_connection is not None:
            model.set_radio_stats(self.radio_connection.stats, now)
        self._check_download(now)
        if not self.screen_stack or not self.is_running:
            return  # shutting down
        screen = self.screen
        for w in screen.query(ModelView):
            w.show(model, now)
        for p in screen.query(LivePlot):
            p.show(model, now)

    # --- input ---------------------------------------------------------------------------------------------

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action == "pilot" and isinstance(self.focused, Input):
            return False  # typing in the command palette
        return True

    def action_pilot(self, name: str) -> None:
        action = action_by_name(self.keymap, name)
        if action is not None:
            self.perform(action)

    def perform(self, action: Action) -> None:
        """Run one key-map action (from a key, the palette or a test)."""
        if action.local is not None:
            getattr(self, f"local_{action.local}")()
            return
        assert action.op is not None
        self.send(action.op, action.arg)

    def send(self, op: Op, arg: int = 0) -> int | None:
        now = self.clock()
        if op == Op.MODE:
            why = leave_safe_refusal(self.model.mode if self.model.mode is not None else Mode.SAFE, arg,
                                     self.model.stick)
            if why is not None:
                self.model.note(now, "error", "term", f"not sent: {mode_name(arg)}: {why}")
                self.notify(why, title=f"{mode_name(arg)} refused", severity="error")
                return None
        if op == Op.WIRELESS and arg == 1 and self.model.primary_ble:
            why = "the handover is asked for over the cable: press 8 on the cable terminal"
            self.model.note(now, "error", "term", f"not sent: wireless handover: {why}")
            self.notify(why, title="wireless handover", severity="warning")
            return None
        conn = self.control_connection()
        if conn is None:
            self.model.note(now, "error", "term", f"not sent: {op_text(op, arg)}: not connected")
            return None
        if op == Op.MODE:
            self.model.note(now, "info", "term", f"request {mode_name(arg)}"
                            + (" over BLE" if conn is self.radio_connection else ""))
        self.model.pending += 1
        return conn.send_command(op, arg)

    def poll_joystick(self) -> None:
        if self.poller is None:
            return
        res = self.poller.poll()
        now = self.clock()
        for msg in res.messages:
            self.model.note(now, "warning" if res.disconnected else "info", "joystick", msg)
        if res.messages:
            self.model.joystick_name = self.poller.name
            self.model.joystick_mapping = self.poller.mapping.name if self.poller.name else ""
        if res.disconnected and self.model.flying:
            self.model.note(now, "error", "joystick", "joystick lost in flight: PANIC")
            self.send(Op.MODE, Mode.PANIC)
        if res.packet is not None:
            self.set_stick(res.packet)

    def set_stick(self, js: Joystick) -> None:
        """A new stick value: to the model and the link at once; the fire button's press is PANIC."""
        self.model.set_stick(js)
        if self.connection is not None:
            self.connection.set_joystick(js)
        if self.radio_connection is not None:  # mirrored: whichever link the board reads has the latest
            self.radio_connection.set_joystick(js)
        fire = bool(js.buttons & Button.FIRE)
        if fire and not self._fire_down:
            self.model.note(self.clock(), "error", "joystick", "fire: PANIC")
            self.send(Op.MODE, Mode.PANIC)
        self._fire_down = fire

    # --- local actions (named in the key map) -------------------------------------------------------------

    def local_help(self) -> None:
        if isinstance(self.screen, HelpScreen):
            self.pop_screen()
        else:
            self.push_screen(HelpScreen(self.keymap))

    def _show(self, name: str) -> None:
        while len(self.screen_stack) > 1:
            self.pop_screen()
        if name != "flight":
            self.push_screen(name)
        self.call_after_refresh(self.render_now)

    def local_show_flight(self) -> None:
        self._show("flight")

    def local_show_plots(self) -> None:
        self._show("plots")

    def local_show_profile(self) -> None:
        self._show("profile")

    def local_show_wireless(self) -> None:
        self._show("wireless")

    def set_screen_stick(self, *, roll: int | None = None, pitch: int | None = None, yaw: int | None = None,
                         lift: int | None = None) -> None:
        """The wireless screen's pad and lift slider: change those axes of the stick, keep the others."""
        s = self.model.stick
        self.set_stick(Joystick(s.roll if roll is None else roll, s.pitch if pitch is None else pitch,
                                s.yaw if yaw is None else yaw, s.lift if lift is None else lift, s.buttons))

    def local_profile(self) -> None:
        self.send(Op.PROFILE)
        self._show("profile")

    def local_clear_events(self) -> None:
        self.model.events.clear()
        self.model.version += 1

    def local_log_download(self) -> None:
        if self.model.download is not None:
            self.model.note(self.clock(), "warning", "term", "a log download is already running")
            return
        if self.connection is None:
            self.model.note(self.clock(), "error", "term", "not sent: log download: not connected")
            return
        self.model.download = LogDownload(started=self.clock())
        self.model.download_note = ""
        self._resumes = 0
        self._resumed_at = -1e9
        self.send(Op.LOG_STATUS)
        self.send(Op.LOG_DOWNLOAD, 0)

    def _check_download(self, now: float) -> None:
        d = self.model.download
        if d is None:
            return
        if d.empty:
            self.model.download = None
            self.model.download_note = "log download: the board's log is empty (F2 starts recording)"
            return
        if d.done:
            self.model.download = None
            problem = d.verify()
            if problem:
                self.model.note(now, "error", "term", f"log download failed: {problem}")
                self.model.download_note = f"log download failed: {problem}"
                return
            stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
            path = self.log_directory / log_filename(stamp)
            self.run_worker(self._save_log(d.data(), path, d.rate_kBps(now)), exclusive=False)
        elif d.used is not None and (
            now - max(d.last_progress, d.started) > DOWNLOAD_STALL_S
            or (d.chunks and d.last_progress > self._resumed_at and self._board_done_sending()
                and now - d.last_progress > DOWNLOAD_GAP_S)
        ):
            first = d.missing()
            if self._resumes >= DOWNLOAD_RESUMES or first is None:
                self.model.download = None
                self.model.download_note = "log download gave up: the board stopped sending"
                self.model.note(now, "error", "term", self.model.download_note)
                return
            self._resumes += 1
            d.last_progress = self._resumed_at = now
            self.send(Op.LOG_DOWNLOAD, first)

    def _board_done_sending(self) -> bool:
        ls = self.model.log_status
        return ls is not None and ls.state != LogState.DOWNLOADING

    async def _save_log(self, data: bytes, path: Path, rate: float) -> None:
        from term.logfile import decode_to_rows

        try:
            rows = await asyncio.to_thread(write_csv, data, path, decode_to_rows)
        except OSError as exc:
            msg = f"cannot write {path}: {exc.strerror}"
            self.model.note(self.clock(), "error", "term", msg)
            self.model.download_note = msg
            return
        msg = f"log saved: {path} ({len(data)} bytes, {rows} rows, {rate:.2f} kB/s)"
        self.model.note(self.clock(), "info", "term", msg)
        self.model.download_note = msg

    # --- command palette ----------------------------------------------------------------------------------

    def download_to(self) -> None:
        """Ask for a directory, then download there."""
        def chosen(path: Path | None) -> None:
            if path is None:
                return
            self.log_directory = path
            self.local_log_download()

        self.push_screen(DirectoryPrompt(self.log_directory), chosen)

    def get_system_commands(self, screen: Screen) -> Iterable[SystemCommand]:
        yield from super().get_system_commands(screen)
        yield SystemCommand("Log: download to a directory…", f"now {self.log_directory}", self.download_to)
        yield SystemCommand("Link: reconnect now", "try every lost link at once (the cable, the BLE radio)",
                            self.reconnect_now)
        yield SystemCommand("Link: hand control back to the cable", "WIRELESS off: the board leaves BLE "
                            "(DISCONNECTED, the connection stays)", lambda: self.send(Op.WIRELESS, 0))
        for b in self.keymap:
            a = b.action
            keys = ", ".join(pretty_key(k) for k in b.keys)
            yield SystemCommand(f"{a.group}: {a.description}", f"key {keys}", _bound(self.perform, a))


def _bound(fn: Callable[[Action], None], action: Action) -> Callable[[], None]:
    return lambda: fn(action)


def _forced(cfg: Config):  # type: ignore[no-untyped-def]
    from term.config import forced_mapping

    return forced_mapping(cfg)
