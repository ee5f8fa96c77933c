"""The Textual app: composes the station (the links), the model (what the screen shows) and the screens.

- The ``Station`` (``term.session.station``) keeps the cable and the radio up, routes commands and sticks, and guards
  what is sent; every event of it updates the ``Model`` in one place (``Model.apply``). The app only reacts to a few
  (a toast for a refused command, exiting on ``Fatal``). Heartbeat ACKs are written by the connections
  themselves, never waiting for the screen.
- The screen is redrawn from the model at a steady rate (``render_hz``), never per byte; the same tick samples the
  links' statistics into the model.
- Pilot keys are priority bindings generated from the key map: they work on every screen (help and plots
  included) except while a text input (the command palette) has focus. A key press goes out at once: the command
  is queued in the session and the connection's timer task is woken to write it. A key map action is either a
  board command (``Station.send``) or a local action, dispatched through a table of callables (``local``).
- The wireless screen is a view of the headless ``Phone`` (``term.session.phone``); its controls post ``PhoneRequest``
  messages up, which the app carries out as the keys would. The joystick poller is read at ``joystick_hz``.
- The app owns controllers, one job each (``term/ui/controllers/``): the log download (``DownloadController``; its
  policy is ``term.session.download``), driven from the render tick and the link events that concern it; the
  parameters (``ParamsController``), the lessons (``LessonController``), the joystick, the replay and the
  session's outputs (recording, live servers).

The routing rules, the reconnect policy and the model's two-link rules: docs/architecture.md and docs/wireless.md.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from textual import events
from textual.app import App, SystemCommand
from textual.command import CommandPalette
from textual.screen import ModalScreen, Screen

from term.core.errors import EXIT_USAGE
from term.core.events import EventsCleared, Fatal, FromLink, NotSent, StationEvent
from term.core.heap import PROCESS_HEAP, freeze_startup, thaw
from term.core.protocol import MODE_TABLE, Joystick, Mode, Op
from term.data.recording import SessionRecorder
from term.data.replay import Replay
from term.input.joystick import JoystickPoller
from term.input.keymap import (
    PRESET_TEXT,
    PRIORITY_IN_FLIGHT,
    Action,
    KeyBinding,
    action_by_name,
    action_for_key,
    pretty_key,
)
from term.lessons.instructor import InstructorClient
from term.lessons.room import Room
from term.session.alarms import Alarms
from term.session.config import Config
from term.session.connection import Connection
from term.session.link_thread import LinkThread, movable, post_taps
from term.session.model import Model
from term.session.phone import Phone, RunAction, SendCommand, SetAxes
from term.session.station import Station
from term.transports.base import Transport
from term.ui.controllers.dialogs import Dialogs
from term.ui.controllers.downloads import DownloadController
from term.ui.controllers.joystick import JoystickController
from term.ui.controllers.lessons import LessonController
from term.ui.controllers.mavlink import MavlinkControl
from term.ui.controllers.motortest import MotorTestController
from term.ui.controllers.outputs import SessionOutputs
from term.ui.controllers.params import ParamsController
from term.ui.controllers.replay import SEEK_S as REPLAY_SEEK_S
from term.ui.controllers.replay import ReplayController
from term.ui.keygate import focus_state, pilot_key_acts
from term.ui.screens.console import ConsoleScreen
from term.ui.screens.dirprompt import DirectoryPrompt
from term.ui.screens.flight import FlightScreen
from term.ui.screens.help import HelpScreen
from term.ui.screens.joystick import JoystickScreen, SaveMapping
from term.ui.screens.motortest import MotorTestScreen
from term.ui.screens.params import ParamsScreen, ReloadParams, SetParam
from term.ui.screens.plots import PlotsScreen
from term.ui.screens.profile import ProfileScreen
from term.ui.screens.wireless import PhoneRequest, WirelessScreen
from term.ui.widgets.base import ModelView
from term.ui.widgets.lesson import LessonBar
from term.ui.widgets.plots import LivePlot

# The footer: the mode keys with PANIC first, then the screens; each with a short label (the help has the long one).
FOOTER_LABELS = {  # the mode table's labels (PANIC, then the ground's modes, then the flight modes), the screens
    **{s.action: s.label for s in sorted(MODE_TABLE.values(), key=lambda s: (s.flight, s.mode != Mode.PANIC, s.mode))
       if s.keys}, "help": "help",
    "show_plots": "plots", "show_flight": "flight", "show_profile": "profile", "show_wireless": "wireless",
    "log_download": "log",
}
FOOTER_ACTIONS = tuple(FOOTER_LABELS)
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
        recorder: SessionRecorder | None = None,
        replay: Replay | None = None,
        instructor: InstructorClient | None = None,
        lesson: int | None = None,
        demo: bool = False,
        lessons_dirs: tuple[Path, ...] = (),
        live: Any = None,
        link_thread: bool | None = None,
        mavlink: Any = None,
    ) -> None:
        """``transport``: the board's link (the cable, or BLE with ``primary_ble``); ``radio``: a BLE transport
        to the same board beside the cable, for the handover; ``start_screen``: "flight" or "wireless".
        ``recorder``: the session recording (the transports already tapped, term.data.recording), kept up to date
        with the station's events and the events list; ``replay``: play a recording instead of flying (no
        transports: the panels show the recording, the pilot's keys play it). ``instructor``: the simulator's
        instructor channel (term --sim): the room view, the lessons (``lesson``: start that one; ``demo``: the
        autopilot's tour; ``lessons_dirs``: a teacher's lessons beside the built-in ones),
        term/ui/controllers/lessons.py. ``live``: the live Foxglove server (term/data/foxglove_server.py), fed the
        events, the link statistics, the truth and, in a replay, the packets; flying, the station hands it each
        packet the links decode, on the link's thread (the taps give it the reads' times and the bytes written).
        ``link_thread``: run the links on their own thread (term/session/link_thread.py); by default they do
        whenever the transports are real ones (serial, BLE). ``mavlink``: the MAVLink ground station's endpoint
        (term/data/mavlink.py), fed like the live server, attached to the station when the app mounts."""
        super().__init__()
        self.config = config or Config()
        self.keymap: tuple[KeyBinding, ...] = self.config.keymap
        self.recorder = recorder
        self.replay = replay
        self.live = live
        self.mavlink = mavlink
        if replay is not None:
            clock = replay.clock  # the panels, plots and events run on the recording's time
            joystick = False
        self.clock = clock
        self.render_hz = render_hz
        self.joystick_hz = joystick_hz
        self.station = self._make_station(transport, radio, primary_ble, session_options, link_thread)
        if live is not None:  # on screen while it serves (the line printed before the screen took over is hidden)
            self.station.model.live_url = str(getattr(live, "url", ""))
        self.phone = Phone()
        self.start_screen = start_screen
        self._want_joystick = joystick
        self.joystick = JoystickController(self.station, self.config, self.send, self.set_stick, self.set_interval,
                                           joystick_hz)
        self.outputs = SessionOutputs(self.station, clock, recorder, live, replaying=replay is not None)
        self.replayer = None
        self.downloads = DownloadController(self.station, clock, self.send, self.control_connection,
                                            lambda work: self.run_worker(work, exclusive=False),
                                            log_directory or self.config.log_directory)
        self.params = ParamsController(self.config, self.station, self.send, replay=replay is not None)
        self.exit_message: str | None = None
        self.alarms = Alarms()
        self.motortest = MotorTestController(self.send, self.station.note, clock)  # the bench test (Ctrl+O)
        self.alarms_rung: list[str] = []  # every alarm the bell was rung for (or would have been, bell off)
        self.lessons = LessonController(self.station, clock, self.keymap, self, instructor, lesson, demo,
                                        lessons_dirs)
        if replay is not None:  # a --sim recording's truth: the room view shows where the craft was
            if replay.has_truth and self.lessons.room is None:
                self.lessons.room = Room()
            self.replayer = ReplayController(replay, self.station, self.render_now, room=self.lessons.room)
        if instructor is not None and (live is not None or recorder is not None):  # the true pose, kept and served
            on_truth = instructor.on_truth
            instructor.on_truth = lambda truth: (self.outputs.truth(truth), on_truth and on_truth(truth))
        self.mav = MavlinkControl(mavlink, self.station, self.notify)  # term --mavlink (controllers/mavlink.py)
        self.dialogs = Dialogs(self)  # the questions (the log's erase, quitting in flight, the motor test)
        self._bind_keys()

    def _make_station(self, transport: Transport | None, radio: Transport | None, primary_ble: bool,
                      session_options: dict[str, float | bool] | None, link_thread: bool | None) -> Station:
        """The model and the station that feeds it, on ``self.clock`` (a replay: the recording's links). The links
        run on their own thread when ``link_thread`` (None: when every transport is a real one)."""
        from term.session.config import JOYSTICK_POLICIES

        clock, replay = self.clock, self.replay
        model = Model(start=clock(), link_name=transport.name if transport else "",
                      radio_name=radio.name if radio is not None else "", primary_ble=primary_ble)
        if replay is not None:  # the links the recording was made over
            model.radio_name = replay.meta.get("radio", "")
            model.primary_ble = replay.meta.get("primary_ble", "") == "1"
        cable_session = {"link_timeout": self.config.link_timeout,
                         **JOYSTICK_POLICIES[self.config.joystick_policy], **(session_options or {})}
        links = [t for t in (transport, radio) if t is not None]
        if link_thread is None:
            link_thread = bool(links) and all(movable(t) for t in links)
        station = Station(model, cable=transport, radio=radio, cable_session=cable_session,
                          radio_session={"link_timeout": self.config.link_timeout}, clock=clock,
                          on_event=self._on_station_event, runner=LinkThread() if link_thread else None,
                          on_packet=None if replay is not None else _fan_out(self.live, self.mavlink))
        for t in links:  # the recording's taps write on this thread, never on the link's
            post_taps(t, station.post)
        return station

    def _bind_keys(self) -> None:
        """The key map's actions as priority bindings; local actions through the table ``local``."""
        self.local: dict[str, Callable[[], None]] = {
            "help": self.toggle_help,
            "show_flight": lambda: self.show_screen("flight"),
            "show_plots": lambda: self.show_screen("plots"),
            "show_profile": lambda: self.show_screen("profile"),
            "show_wireless": lambda: self.show_screen("wireless"),
            "profile": self.ask_profile,
            "clear_events": self.clear_events,
            "log_download": self.downloads.start,
            "log_reset": self.dialogs.log_erase,
            "show_joystick": lambda: self.show_screen("joystick"),
            "show_params": lambda: self.show_screen("params"),
            "show_console": lambda: self.show_screen("console"),
            "motor_test": self.dialogs.motor_test,
        }
        unknown = {b.action.local for b in self.keymap if b.action.local} - set(self.local)
        if unknown:
            raise ValueError(f"key map: no local action named {', '.join(sorted(unknown))}")
        if self.replay is not None:
            self.keymap = tuple(b for b in self.keymap if b.action.local is not None)  # no board to command
            for keys, action, text in REPLAY_KEYS:
                self._bindings.bind(keys, action, text, priority=True)
        order = {name: i for i, name in enumerate(FOOTER_ACTIONS)}  # the footer shows them in binding order
        for b in sorted(self.keymap, key=lambda b: order.get(b.action.name, len(order))):
            name = b.action.name
            for i, key in enumerate(b.keys):  # one binding per key: which key it was decides who gets it (keygate)
                self._bindings.bind(
                    key, f"pilot('{name}', '{key}')", FOOTER_LABELS.get(name, b.action.description),
                    show=i == 0 and name in FOOTER_LABELS,
                    key_display=" ".join(pretty_key(k) for k in b.keys), priority=True,
                )

    # --- what the app is made of --------------------------------------------------------------------------

    @property
    def model(self) -> Model:
        return self.station.model

    @model.setter
    def model(self, model: Model) -> None:  # a test may show a model it built
        self.station.model = model

    @property
    def connection(self) -> Connection | None:
        """The board's link while it is up."""
        return self.station.cable_connection

    @property
    def radio_connection(self) -> Connection | None:
        return self.station.radio_connection

    @property
    def transport(self) -> Transport | None:
        return None if self.station.cable is None else self.station.cable.transport

    @property
    def radio(self) -> Transport | None:
        return None if self.station.radio is None else self.station.radio.transport

    def control_connection(self) -> Connection | None:
        """The connection commands go over: the radio once the board flies over BLE, else the board's link."""
        link = self.station.control()
        return None if link is None else link.connection

    # --- life cycle ---------------------------------------------------------------------------------------

    def get_default_screen(self) -> Screen[None]:
        return FlightScreen(self.keymap, self.lessons.room, id="flight")

    async def on_mount(self) -> None:
        # The link has its own thread, plots are drawn on a worker thread and serial bytes arrive on one: hand the
        # GIL over within 1 ms (Python's default is 5 ms), so heartbeat answers and key presses never wait behind
        # a frame being drawn.
        sys.setswitchinterval(0.001)
        self.install_screen(PlotsScreen(self.config.plot_series, self.config.plot_window), "plots")
        self.install_screen(ProfileScreen(), "profile")
        self.install_screen(WirelessScreen(self.phone), "wireless")
        self.install_screen(JoystickScreen(lambda: self.joystick.poller), "joystick")
        self.install_screen(ParamsScreen(lambda: self.model, self.can_fly), "params")
        self.install_screen(ConsoleScreen(), "console")
        self.set_interval(1.0 / self.render_hz, self.render_now)
        await self.station.start()
        self.mav.start(self.downloads.start)
        if self.start_screen != "flight":
            self.show_screen(self.start_screen)
        if self._want_joystick:
            self.call_after_refresh(self.joystick.start)
        self.lessons.mount()
        self.outputs.recording_failed()  # a recording that could not start: said before the first flight
        self.render_now()
        freeze_startup()  # widgets and libraries built: no full collection walks them again (term/core/heap.py)

    def _on_station_event(self, ev: StationEvent) -> None:
        """The app's reactions to the station's events (the model has them already)."""
        self.outputs.station_event(ev)
        self.mav.station_event(ev)
        self.lessons.on_station_event(ev)
        if type(ev) is FromLink:
            self.downloads.on_link_event(ev.event)
            self.params.on_station_event(ev)
        elif type(ev) is Fatal:
            self._fatal(ev.message, ev.code)
        elif type(ev) is NotSent and ev.title is not None:
            self.notify(ev.why, title=ev.title, severity=ev.severity)

    @property
    def log_directory(self) -> Path:
        return self.downloads.log_directory

    def download_to(self) -> None:
        """Ask for a directory, then download there."""
        def chosen(path: Path | None) -> None:
            if path is not None:
                self.downloads.log_directory = path
                self.downloads.start()

        self.push_screen(DirectoryPrompt(self.downloads.log_directory, about=frozenset({Mode.SAFE})), chosen)

    def on_set_param(self, message: SetParam) -> None:
        self.params.set_param(message.param, message.value)

    def on_reload_params(self, message: ReloadParams) -> None:
        self.params.reload()

    def show_caption(self, text: str) -> None:
        """The lesson bar's line (the lessons' host): on the flight screen only."""
        try:
            bar = self.screen.query_one(LessonBar)
        except Exception:
            return  # another screen, or shutting down
        bar.show_text(text)

    def on_model_view_resized(self, message: ModelView.Resized) -> None:
        self.call_later(self.render_now)

    def reconnect_now(self) -> None:
        """The palette's "reconnect now": every dead link is tried at once (and then with the usual pauses)."""
        self.station.reconnect_now()

    async def on_unmount(self) -> None:
        await self.shutdown()

    async def shutdown(self) -> None:
        await self.station.shutdown()
        self.joystick.close()
        thaw()

    def _fatal(self, message: str, code: int = EXIT_USAGE) -> None:
        self.exit_message = message
        self.exit(code, return_code=code)

    # --- rendering ----------------------------------------------------------------------------------------

    def render_now(self) -> None:
        if self.replayer is not None:
            self.sub_title = self.replayer.step()
        now = self.clock()
        self.station.sample()
        PROCESS_HEAP.tick(time.monotonic())  # glibc's free pages back to the system once a minute (term/core/heap.py)
        self.downloads.tick(now)
        if self.replay is None:
            for alarm in self.alarms.update(self.model, now):
                self.alarms_rung.append(alarm)
                if self.config.bell:
                    self.bell()
        self.outputs.tick(now)
        self._motor_test_tick(now)
        self.mav.tick(now)
        if not self.screen_stack or not self.is_running:
            return  # shutting down
        self.dialogs.close_stale()
        model = self.model
        for screen in self._live_screens():
            for w in screen.query(ModelView):
                w.show(model, now)
            for p in screen.query(LivePlot):
                p.show(model, now)

    def _live_screens(self) -> list[Screen[object]]:
        """The screen on top and, under a dialog (a summary, a question, the help), the screens it lets show
        through, down to the first full screen: their figures stay live, never frozen behind it."""
        shown: list[Screen[object]] = []
        for screen in reversed(self.screen_stack):
            shown.append(screen)
            if not isinstance(screen, ModalScreen):
                break
        return shown

    # --- input ---------------------------------------------------------------------------------------------

    def can_fly(self) -> bool:
        """Out of SAFE (as far as the board said) on a live board: PANIC and SAFE are never text then."""
        mode = self.model.mode
        return mode is not None and mode != Mode.SAFE and self.replay is None

    async def on_event(self, event: events.Event) -> None:
        # Any key stops a running motor test first; on its own screen (SAFE) that key is spent on the stop.
        if type(event) is events.Key and self.motortest.key() and isinstance(self.screen, MotorTestScreen) \
                and not self.can_fly():
            self.call_later(self.render_now)
            return
        # Before Textual's bindings: a focused text box hides printable keys from them (check_consume_key).
        if type(event) is events.Key and not event.is_forwarded and self.can_fly():
            action = action_for_key(self.keymap, event.key)
            if action is not None and action.name in PRIORITY_IN_FLIGHT:
                self.perform(action)
                return
        elif type(event) is events.Key and not event.is_forwarded and event.key == "escape" and self._dialog_on_top():
            # In SAFE (or with no board) Esc closes any dialog: PANIC would change nothing there (the motors are
            # off) and the pilot means "close". Out of SAFE Esc stays PANIC (above).
            self.screen.dismiss(getattr(self.screen, "CANCEL", None))  # the dialog's own "no"
            return
        await super().on_event(event)

    def _dialog_on_top(self) -> bool:
        return isinstance(self.screen, ModalScreen) and not isinstance(self.screen, CommandPalette)

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action == "pilot" and len(parameters) == 2:  # a key (term/ui/keygate.py): the pilot's or the widget's
            typing, claimed = focus_state(self)
            return pilot_key_acts(str(parameters[0]), str(parameters[1]), typing=typing, claimed=claimed,
                                  can_fly=self.can_fly())
        return True

    def action_pilot(self, name: str, key: str = "") -> None:
        action = action_by_name(self.keymap, name)
        if action is not None:
            self.perform(action)

    def perform(self, action: Action) -> None:
        """Run one key-map action (from a key, the palette, the phone or a test)."""
        self.lessons.on_action(action)  # a pilot's own board command takes over from the autopilot
        if action.local is not None:
            self.local[action.local]()
            return
        self.mav.pilot_command()  # ... and from a MAVLink ground station that was handed control
        assert action.op is not None
        self.send(action.op, action.arg)

    def send(self, op: Op, arg: int = 0) -> int | None:
        """A command over the link that carries control, if the station's guards let it go; its cmd_id."""
        return self.station.send(op, arg)

    def set_stick(self, js: Joystick) -> None:
        """A new stick value: to the model and the links at once; the fire button's press is PANIC."""
        self.station.set_stick(js)

    def on_save_mapping(self, message: SaveMapping) -> None:
        """The joystick screen\'s "save": the mapping into the config file as the device\'s own."""
        self.joystick.save_mapping(message.mapping, message.device)

    def on_phone_request(self, message: PhoneRequest) -> None:
        """The phone's controls (the wireless screen): carried out as the keys would."""
        for r in message.requests:
            if type(r) is SetAxes:
                self.station.set_axes(roll=r.roll, pitch=r.pitch, yaw=r.yaw, lift=r.lift)
            elif type(r) is RunAction:
                self.action_pilot(r.name)
            elif type(r) is SendCommand:
                self.send(r.op, r.arg)

    # --- local actions (named in the key map) -------------------------------------------------------------

    def close_top_screen(self) -> None:
        """Pop the top screen. The command palette first stops its search, as its own Esc does: its worker would
        otherwise look for its list after the palette is gone, and a worker's error ends the app (an F-key pressed
        while the palette searches, in flight too)."""
        stop_search = getattr(self.screen, "_cancel_gather_commands", None)  # Textual's own Esc path
        if isinstance(self.screen, CommandPalette) and stop_search is not None:
            stop_search()
        self.pop_screen()

    def toggle_help(self) -> None:
        if isinstance(self.screen, HelpScreen):
            self.pop_screen()
        else:
            self.push_screen(HelpScreen(self.keymap, PRESET_TEXT.get(self.config.key_preset, "")))

    def ask_log_erase(self) -> None:
        self.dialogs.log_erase()

    async def action_quit(self) -> None:
        self.dialogs.quit()

    def show_screen(self, name: str) -> None:
        while len(self.screen_stack) > 1:
            self.close_top_screen()
        if name != "flight":
            self.push_screen(name)
        self.call_after_refresh(self.render_now)

    def ask_profile(self) -> None:
        self.send(Op.PROFILE)
        self.show_screen("profile")

    def _motor_test_tick(self, now: float) -> None:
        """The motor test follows the board and the link; leaving its screen by any way stops it."""
        mt = self.motortest
        mt.tick(self.model, now)
        if mt.running and self.screen_stack and not isinstance(self.screen, MotorTestScreen):
            mt.stop("left the motor test screen")

    def clear_events(self) -> None:
        self.station.emit(EventsCleared())

    # --- command palette ----------------------------------------------------------------------------------

    def get_system_commands(self, screen: Screen) -> Iterable[SystemCommand]:
        yield from super().get_system_commands(screen)
        yield SystemCommand("Log: download to a directory…", f"now {self.downloads.log_directory}", self.download_to)
        yield SystemCommand("Link: reconnect now", "try every lost link at once (the cable, the BLE radio)",
                            self.reconnect_now)
        yield SystemCommand("Link: hand control back to the cable", "WIRELESS off: the board leaves BLE "
                            "(DISCONNECTED, the connection stays)", lambda: self.send(Op.WIRELESS, 0))
        yield from self.mav.commands()
        yield from self.lessons.commands()
        for b in self.keymap:
            a = b.action
            keys = ", ".join(pretty_key(k) for k in b.keys)
            yield SystemCommand(f"{a.group}: {a.description}", f"key {keys}", _bound(self.perform, a))


    # --- recording and replay (term/data/recording.py, term/data/replay.py) ---------------------------------------

    @property
    def poller(self) -> JoystickPoller | None:
        return self.joystick.poller

    def replay_seek(self, t: float) -> None:
        if self.replayer is not None:
            self.replayer.seek(t)

    def action_replay(self, what: str) -> None:
        if self.replayer is not None:
            self.notify(self.replayer.act(what), timeout=1.5)


REPLAY_KEYS = (  # term replay: the pilot's keys have no board to command; these play the recording
    ("space", "replay('pause')", "pause / play"),
    ("right", "replay('forward')", f"{REPLAY_SEEK_S:g} s on"),
    ("left", "replay('back')", f"{REPLAY_SEEK_S:g} s back"),
    ("plus,equals_sign", "replay('faster')", "faster"),
    ("minus", "replay('slower')", "slower"),
    ("home", "replay('start')", "from the start"),
)




def _fan_out(*sinks: Any) -> Callable[[str, Any], None] | None:
    """The station's ``on_packet`` for each live output there is (the Foxglove server, the MAVLink endpoint)."""
    calls = [s.link_packet for s in sinks if s is not None]
    if not calls:
        return None
    if len(calls) == 1:
        return calls[0]

    def each(link: str, pkt: Any) -> None:
        for call in calls:
            call(link, pkt)

    return each


def _bound(fn: Callable[[Action], None], action: Action) -> Callable[[], None]:
    return lambda: fn(action)
