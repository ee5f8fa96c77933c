"""The one thing every panel shares: it renders itself from the model when the app's render tick asks, and every
board figure it draws is a ``Reading`` (term.core.freshness) drawn by ``figure``: dimmed with its age when stale, "—"
when the link that carries control does not bring it, ">"/"<" at its field's limit. A panel redraws when the
model changes and, without a change, when one of its figures goes stale or its age should tick on."""

from __future__ import annotations

import math
import re
import time

from rich.console import RenderableType
from rich.text import Text
from textual.message import Message
from textual.widget import Widget

from term.core.freshness import Reading, next_age_change
from term.session.model import Model


class ModelView(Widget):
    """A panel drawn from the ``Model``. The app calls ``show`` at its render rate; widgets never read I/O.

    Not a ``Static``: ``Static.update`` asks for a new layout of the whole screen on every call, which at 15 Hz
    was most of the terminal's CPU. Every panel has a fixed size in app.tcss, so a new frame only needs the panel
    itself repainted.
    """

    class Resized(Message):
        """A panel changed size: the app redraws the screen from the model at once."""

    DEFAULT_CSS = "ModelView { height: auto; }"

    # Panels whose text depends on time alone (ages, rates) redraw even when the model did not change.
    TIME_DEPENDENT = False
    # Panels of slow or noisy figures (battery, pressure, link statistics) repaint at most this often; a change
    # of ``urgent(model)`` (a threshold crossed, the link lost) repaints at once.
    MAX_HZ: float | None = None

    def __init__(self, *, id: str | None = None, classes: str | None = None) -> None:  # noqa: A002
        super().__init__(id=id, classes=classes)
        self._shown_version = -1
        self._shown: RenderableType = Text("")
        self._painted = -1e9
        self._urgent: object = None
        self._expires = math.inf  # when a figure shown goes stale, or a stale one's age ticks on
        self.readings: dict[str, Reading] = {}  # the figures of the last frame (for the tests)
        self._subtitle = ""

    def show(self, model: Model, now: float) -> None:
        due = now >= self._expires
        if not self.TIME_DEPENDENT and model.version == self._shown_version and not due:
            return
        if self.MAX_HZ is not None:
            wall = time.monotonic()  # a CPU budget: wall time, whatever clock the model runs on
            urgent = (self.urgent(model), model.over_ble)  # a hand-over changes what is carried: show it at once
            if wall - self._painted < 1.0 / self.MAX_HZ and urgent == self._urgent and not due:
                return
            self._painted, self._urgent = wall, urgent
        self._shown_version = model.version
        self._expires = math.inf
        self.readings = {}
        content = self.render_model(model, now)
        # Rich Text compares text and styles: an identical frame is not repainted.
        if isinstance(content, Text) and isinstance(self._shown, Text) and content == self._shown:
            return
        self._shown = content
        self.refresh()

    def render(self) -> RenderableType:
        return self._shown

    def on_resize(self) -> None:
        self._shown_version = -1  # panels lay themselves out to their size: redraw now, not at the next change
        self._painted = -1e9
        self.post_message(self.Resized())  # the app redraws every panel now (messages up: no call into the app)

    def urgent(self, model: Model) -> object:
        return None

    def read(self, model: Model, name: str, now: float, *, figure: bool = True) -> Reading:
        """A figure for this frame; the panel redraws by itself when it goes stale (and then once a second).
        ``figure``: the panel shows it as a number (so it must show its bound and its staleness), not only uses it
        (a picture, a flag that decides a word)."""
        r = model.reading(name, now)
        if figure:
            self.readings[name] = r
        if r.known:
            self._expires = min(self._expires, now + (r.limit - r.age if r.fresh else next_age_change(r.age)))
        return r

    def mark(self, *readings: Reading) -> None:
        """The panel's bottom border says what is not fresh among ``readings``: their mark, or, when they differ
        (figures from two packets, e.g. the pressure not over BLE and the height from Compact2 a second old), each
        mark after the names of its figures."""
        marks: dict[str, list[str]] = {}
        for r in readings:
            if r.mark:
                marks.setdefault(r.mark, []).append(r.name)
        if len(marks) <= 1:
            self.subtitle(next(iter(marks), ""))
        else:
            self.subtitle(" · ".join(f"{', '.join(names)}: {mark}" for mark, names in marks.items()))

    def subtitle(self, text: str) -> None:
        """Set the bottom border's text; only a change repaints (Textual repaints on every assignment)."""
        if text != self._subtitle:
            self._subtitle = text
            self.border_subtitle = Text(text) if text else None

    def render_model(self, model: Model, now: float) -> RenderableType:
        raise NotImplementedError


# --- figures with their freshness ----------------------------------------------------------------------------

STALE_STYLE = "dim"
STATUS_LINE_S = 15.0  # a status line (the download panel's, F11's) this long, then it goes: the events list keeps it
_PRECISION = re.compile(r"\.(\d+)[eEfF%]$")


def _format(value: float, spec: str) -> str:
    if spec.endswith("d"):
        return format(int(round(value)), spec)
    m = _PRECISION.search(spec)
    if value == 0.0 or (m and spec[-1] in "fF" and round(value, int(m.group(1))) == 0.0):
        value = 0.0  # never "-0" (a value that rounds to zero has no sign)
    return format(value, spec)


def figure(r: Reading, spec: str, unit: str = "", style: str = "", pad: str = "") -> Text:
    """A reading as text in ``spec`` (after ``pad``, in the same style): "—" when unknown or not shown (stale and
    not carried by the current link), "?" when not a number, at its field's limit as ">" or "<" that limit
    (rounded toward it, so it stays true), dimmed when stale."""
    width = len(_format(0, spec))
    if not r.shown or r.value is None:
        return Text(pad + "—".rjust(width) + unit, style=STALE_STYLE)
    if r.bound == "?":
        return Text(pad + "?".rjust(width) + unit, style="bold red")
    if r.bound and r.edge is not None:
        m = _PRECISION.search(spec)
        k = 10 ** (int(m.group(1)) if m else 0)
        edge = math.floor(r.edge * k) / k if r.bound == ">" else math.ceil(r.edge * k) / k
        return Text(pad + r.bound + _format(edge, spec) + unit, style=STALE_STYLE if r.stale else style or "bold")
    return Text(pad + _format(float(r.value), spec) + unit, style=STALE_STYLE if r.stale else style)
