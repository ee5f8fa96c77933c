"""The app's questions, one job: a question before something that cannot be taken back (the log's erase, quitting
while the motors run, the motor test), each a ConfirmScreen with its answer, and the rule that a question about
some modes closes itself, with a line, once the board is in another (issue 34: the erase question stayed over the
panels after the board left SAFE, where Esc is PANIC).

The app owns one (``TermApp.dialogs``); its key actions and Ctrl+Q call it, its render tick calls
``close_stale``."""

from __future__ import annotations

from typing import Any

from textual.screen import ModalScreen

from term.core.protocol import FLIGHT_MODES, Mode, Op
from term.session.texts import mode_name
from term.ui.screens.confirm import ConfirmScreen
from term.ui.screens.motortest import MotorTestScreen

QUIT_PANIC_WAIT_S = 0.5  # quitting in flight: the PANIC command's time to reach the board before the link closes


class Dialogs:
    """The questions of ``app`` (a TermApp: its screens, its station and model, ``send``)."""

    def __init__(self, app: Any) -> None:
        self.app = app

    def log_erase(self) -> None:
        """F4: erase the flash log, after a question that says how much would be gone (the board is asked for
        its log status first, so the count is its latest)."""
        app = self.app
        if app.control_connection() is None:
            app.station.note("error", "term", "not sent: log erase: not connected")
            return
        if app.model.mode is not None and app.model.mode != Mode.SAFE:  # a question about SAFE: not in flight
            app.station.note("error", "term", f"not sent: log erase: only in SAFE (the board is in "
                             f"{mode_name(app.model.mode)})")
            return
        app.send(Op.LOG_STATUS)

        def question() -> str:
            ls = app.model.log_status
            what = ("how much is in it: asking the board…" if ls is None else
                    f"{ls.records} records ({ls.used / 1000:.1f} kB) will be gone")
            return f"Erase the board's flash log? {what}.\nDownload it first with F5 if you want to keep it."

        def answer(yes: bool | None) -> None:
            if yes:
                app.send(Op.LOG_RESET)
            elif yes is not None:  # (None: closed by the app, said there)
                app.station.note("info", "term", "log erase cancelled: nothing erased")

        app.push_screen(ConfirmScreen(question, "erase the log", "keep it", title="erase the flash log",
                                      about=frozenset({Mode.SAFE})), answer)

    def quit(self) -> None:
        """Ctrl+Q. While the motors run it asks first; quitting then sends PANIC before it goes (and says so), so
        the board descends under control at once rather than after its link timeout."""
        app = self.app
        mode, motion = app.model.mode, app.model.motion
        turning = motion is None or any((motion.ae1, motion.ae2, motion.ae3, motion.ae4))
        running = mode in FLIGHT_MODES or (mode == Mode.PANIC and turning)  # (a PANIC landed on the pad: no)
        if not running or app.replay is not None or app.control_connection() is None:
            app.exit()
            return
        if isinstance(app.screen, ConfirmScreen):
            return  # already asking

        def answer(yes: bool | None) -> None:
            if yes is None:
                return  # closed by the app (the motors stopped: Ctrl+Q quits at once now), said there
            if not yes:
                app.station.note("info", "term", "quit cancelled: still flying")
                return
            if app.model.mode in FLIGHT_MODES:
                app.send(Op.MODE, Mode.PANIC)
                app.exit_message = "PANIC sent before quitting: the board descends and lands by itself"
                app.station.note("error", "term", app.exit_message)
                app.set_timer(QUIT_PANIC_WAIT_S, app.exit)  # time for the PANIC to go out (and be retried)
            else:
                app.exit()

        text = (f"The motors are running ({mode_name(mode)}).\nQuitting sends PANIC first: the board descends and "
                "lands by itself." if mode in FLIGHT_MODES else
                "PANIC is in progress: the board lands by itself.\nQuit the terminal anyway?")
        app.push_screen(ConfirmScreen(text, "PANIC and quit" if mode in FLIGHT_MODES else "quit", "keep flying",
                                      title="quit while the motors run?",
                                      about=frozenset(FLIGHT_MODES) | {Mode.PANIC}), answer)

    def motor_test(self) -> None:
        """Ctrl+O: the bench motor test, after "props off?" (term/ui/screens/motortest.py)."""
        app = self.app
        why = app.motortest.refusal(app.model)
        if why is not None or app.replay is not None:
            app.station.note("error", "term", f"motor test: {why or 'not in a replay'}")
            return

        def answer(yes: bool | None) -> None:
            if yes:
                app.push_screen(MotorTestScreen(app.motortest))
            else:
                app.station.note("info", "term", "motor test cancelled")

        app.push_screen(ConfirmScreen(
            "Are the PROPELLERS OFF?\nThe motor test spins motors on the bench; with props on the craft can jump or "
            "cut.\nTake every propeller off first.", "props are off: test", "cancel", title="motor test"), answer)

    def close_stale(self) -> None:
        """A dialog about some modes (``about``: the erase question about SAFE) closes itself, with a line, once the
        board is in another: out of SAFE Esc is PANIC, and a question left over the panels hides the flight."""
        app = self.app
        screen = app.screen
        about = getattr(screen, "about", None)
        mode = app.model.mode
        if about is None or mode is None or mode in about or not isinstance(screen, ModalScreen):
            return
        if not screen.is_mounted:
            return  # (its own mount first: the next tick closes it)
        title = getattr(screen, "title_text", "") or "dialog"
        app.station.note("warning", "term", f"{title}: closed, nothing done: the board is in {mode_name(mode)} now")
        screen.dismiss(None)
