"""The lessons' rig: the terminal's side as the app wires it, minus the screen, and the simulated board with its
instructor, on one simulated clock (bench/lessons.py describes it; tests/lessons/test_lessons.py and
tests/lessons/test_demo.py use it)."""

from __future__ import annotations

from typing import Any

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.hosts.instructor import Instructor
from fcb_sim.world.physics import World
from term.core.events import CABLE, RADIO, FromLink, LinkDown, LinkUp, StationEvent
from term.core.link import LinkSession, LinkStats, PacketReceived
from term.core.protocol import INSTRUCTOR_TRUTH_HZ, Event, Joystick, LogChunk, LogStatus
from term.input.keymap import DEFAULT_KEYMAP, action_by_name
from term.lessons.autopilot import COMMANDS, Press, Stick
from term.lessons.driver import LessonDriver, Tick
from term.lessons.engine import Result
from term.lessons.instructor import Truth, parse_line
from term.lessons.spec import DEMO, Lesson, load_script
from term.session.config import JOYSTICK_POLICIES, Config
from term.session.download import DONE, EMPTY, FAILED, RUNNING, LogDownloader
from term.session.model import Model
from term.session.station import RADIO_SESSION, LinkPolicy, Station, StationLink

STEP_US = 2000  # the UART moves 23 bytes per step at 115200 baud; the board runs every task at its own time
TICK_S = 1.0 / INSTRUCTOR_TRUTH_HZ  # the driver's tick, at the truth's rate (as the app's lesson timer)
RENDER_S = 1.0 / 12.0  # the link statistics are sampled at the app's render rate


class _Named:
    """What a StationLink needs of its transport here: a name."""

    def __init__(self, name: str) -> None:
        self.name = name


class _SessionLink:
    """What the station needs of a ``Connection``: the session on the rig's clock, no pump."""

    def __init__(self, session: LinkSession, rig: Rig) -> None:
        self.session = session
        self.rig = rig

    def send_command(self, op: Any, arg: int = 0) -> int:
        return self.session.send_command(op, arg, self.rig.now)

    def set_joystick(self, js: Joystick) -> None:
        self.session.set_joystick(js)

    @property
    def stats(self) -> LinkStats:
        return self.session.stats_at(self.rig.now)


class Rig:
    """The terminal and the simulated board on one simulated clock (module docstring)."""

    def __init__(self, seed: int = 1, *, radio: bool = True) -> None:
        cfg = Config()
        self.now = 0.0
        self.board = Board(BoardConfig(seed=seed), world=World(seed))
        self.instructor = Instructor(self.board, on_radio_cut=self._cut_radio)
        self.model = Model(start=0.0, link_name="rig cable", radio_name="rig radio" if radio else "")
        self.station = Station(self.model, clock=lambda: self.now, on_event=self._on_event)
        self.station.running = True
        self.driver = LessonDriver()
        self.events: list[StationEvent] = []
        self.results: list[Result] = []
        self.autopilot_ended: list[str] = []
        self.refused_situations: list[str] = []
        self.captions: list[str] = []  # every caption line shown, in order (the app's LessonBar)
        self.heights: list[tuple[float, float]] = []  # (time, true height) at every tick
        self.download: LogDownloader | None = None
        self.saved: bytes | None = None
        session = {"link_timeout": cfg.link_timeout, **JOYSTICK_POLICIES[cfg.joystick_policy]}
        self.cable = LinkSession(0.0, **session)
        self.station.cable = self._attach(CABLE, self.cable, "rig cable", session)
        self.phone: LinkSession | None = None
        self._radio_back: float | None = None
        self._radio_session = {**RADIO_SESSION, "link_timeout": cfg.link_timeout}
        if radio:
            self._radio_up(again=False)
        self.board.uart_receive(self.cable.hello())
        self._next_tick = 0.0
        self._next_render = 0.0

    def _attach(self, role: str, session: LinkSession, name: str, options: dict[str, Any]) -> StationLink:
        link = StationLink(self.station, role, _Named(name), LinkPolicy(options))  # type: ignore[arg-type]
        link.connection = _SessionLink(session, self)  # type: ignore[assignment]
        self.station.emit(LinkUp(role, name, again=False))
        return link

    def _radio_up(self, again: bool) -> None:
        self.phone = LinkSession(self.now, **self._radio_session)
        self.phone.set_joystick(self.model.stick)
        self.board.ble_connected()
        self.station.radio = self._attach(RADIO, self.phone, "rig radio", self._radio_session)
        self.board.ble_receive(self.phone.hello())

    def _cut_radio(self, seconds: float) -> str | None:
        if self.phone is None:
            return "radio: not connected"
        self.phone = None
        if self.station.radio is not None:
            self.station.radio.connection = None
        self.board.ble_disconnected()
        self.station.emit(LinkDown(RADIO, "out of range (the instructor's radio cut)"))
        self._radio_back = self.now + seconds
        return None

    # --- the terminal's reactions (what TermApp does) --------------------------------------------------------

    def _on_event(self, ev: StationEvent) -> None:
        self.events.append(ev)
        self.driver.event(ev, self.model, self.now)
        d = self.download
        if d is not None and type(ev) is FromLink:
            inner = ev.event
            if type(inner) is not PacketReceived or type(inner.packet) in (LogChunk, LogStatus, Event):
                d.on_event(inner, self.now)

    def perform(self, name: str) -> None:
        """A key map action, as TermApp.perform does it."""
        if name in COMMANDS:
            self.station.send(*COMMANDS[name])
            return
        action = action_by_name(DEFAULT_KEYMAP, name)
        if action is None:
            raise ValueError(f"no action {name!r}")
        if action.local == "log_download":
            self.download = LogDownloader(started=self.now)
            self.model.download = self.download
            return
        if action.local is not None:
            return  # screens and help: nothing to do without a screen
        assert action.op is not None
        self.station.send(action.op, action.arg)

    def _download_tick(self) -> None:
        d = self.download
        if d is None:
            return
        req = d.poll(self.now)
        if req is not None:
            d.sent(self.station.send(req.op, req.arg), self.now)
        if d.state == RUNNING:
            return
        self.download = self.model.download = None
        if d.state == DONE:
            self.saved = d.data()
            self.model.download_note = f"log saved: rig ({len(self.saved)} bytes)"
        elif d.state in (EMPTY, FAILED):
            self.model.download_note = f"log download {d.state}: {d.reason}"

    def apply_tick(self, tick: Tick) -> None:
        for cmd in tick.situations:
            why = self.instructor.apply(cmd, self.board.now / 1e6)
            if why is not None:
                self.refused_situations.append(why)
        for act in tick.acts:
            if type(act) is Press:
                self.perform(act.action)
            elif type(act) is Stick:
                self.station.set_stick(act.js)
        if tick.result is not None:
            self.results.append(tick.result)
        if tick.autopilot_ended is not None:
            self.autopilot_ended.append(tick.autopilot_ended)
        caption = self.driver.caption
        if caption and (not self.captions or self.captions[-1] != caption):
            self.captions.append(caption)

    # --- the clock ----------------------------------------------------------------------------------------

    def step(self) -> None:
        self.now += STEP_US / 1e6
        t = self.now
        b, inst = self.board, self.instructor
        b.advance(round(t * 1e6))
        board_s = b.now / 1e6
        down = b.uart_transmit()
        cable_open = inst.cable_open(board_s)
        if cable_open and down:
            for ev in self.cable.receive(down, t):
                self.station.emit(FromLink(CABLE, ev))
        for ev in self.cable.poll(t):
            self.station.emit(FromLink(CABLE, ev))
        up = self.cable.data_to_send(t)
        if cable_open and up:
            b.uart_receive(up)
        phone = self.phone
        if phone is not None:
            notes = b"".join(b.wireless.notifications())
            for ev in (phone.receive(notes, t) if notes else []) + phone.poll(t):
                self.station.emit(FromLink(RADIO, ev))
            data = phone.data_to_send(t)
            if data and self.phone is phone:
                b.ble_receive(data)
        elif self._radio_back is not None and t >= self._radio_back:
            self._radio_back = None
            self._radio_up(again=True)
        if t >= self._next_tick:
            self._next_tick += TICK_S
            inst.tick(board_s)
            sample = parse_line(inst.truth_line(board_s))
            if isinstance(sample, Truth):
                self.driver.truth(sample)
                self.heights.append((t, sample.h))
            self.apply_tick(self.driver.tick(self.model, t))
            self._download_tick()
        if t >= self._next_render:
            self._next_render += RENDER_S
            self.station.sample()

    def run(self, seconds: float, stop: Any = None) -> None:
        end = self.now + seconds
        while self.now < end and not (stop is not None and stop()):
            self.step()

    def truth(self) -> Any:
        return self.board.world.truth

    # --- lessons ------------------------------------------------------------------------------------------

    def fly_lesson(self, lesson: Lesson, script: Any = None, limit_s: float = 300.0, *,
                   stop_when_flown: bool = False) -> Result:
        """One attempt at ``lesson``, flown by ``script`` (default: the lesson's own [[show]]); its result.
        ``stop_when_flown``: the pilot stops the lesson once the script has ended (the palette's "Lesson: stop"),
        rather than waiting out a step's own time limit."""
        from term.lessons.autopilot import Autopilot

        d = self.driver
        n = len(self.results)
        ended = len(self.autopilot_ended)
        d.start_lesson(lesson, self.now, show=script is None)
        if script is not None:
            d.autopilot = Autopilot(tuple(script), self.now, "test pilot")
        self.run(limit_s, lambda: len(self.results) > n or (stop_when_flown and len(self.autopilot_ended) > ended))
        if len(self.results) == n and stop_when_flown:
            result = d.stop(self.model, self.now)
            if result is not None:
                self.results.append(result)
        if len(self.results) == n:
            result = d.stop(self.model, self.now, f"no result within {limit_s:g} s")
            assert result is not None
            self.results.append(result)
        return self.results[-1]

    def fly_demo(self, limit_s: float = 400.0) -> str:
        title, goal, script = load_script(DEMO, (b.action.name for b in DEFAULT_KEYMAP))
        self.driver.start_script(title, goal, script, self.now)
        n = len(self.autopilot_ended)
        self.run(limit_s, lambda: len(self.autopilot_ended) > n)
        return self.autopilot_ended[-1] if len(self.autopilot_ended) > n else "still flying"
