"""The one thing every panel shares: it renders itself from the model when the app's render tick asks."""

from __future__ import annotations

import time

from rich.console import RenderableType
from rich.text import Text
from textual.widget import Widget

from term.model import Model


class ModelView(Widget):
    """A panel drawn from the ``Model``. The app calls ``show`` at its render rate; widgets never read I/O.

    Not a ``Static``: ``Static.update`` asks for a new layout of the whole screen on every call, which at 15 Hz
    was most of the terminal's CPU. Every panel has a fixed size in app.tcss, so a new frame only needs the panel
    itself repainted.
    """

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

    def show(self, model: Model, now: float) -> None:
        if not self.TIME_DEPENDENT and model.version == self._shown_version:
            return
        if self.MAX_HZ is not None:
            wall = time.monotonic()  # a CPU budget: wall time, whatever clock the model runs on
            urgent = self.urgent(model)
            if wall - self._painted < 1.0 / self.MAX_HZ and urgent == self._urgent:
                return
            self._painted, self._urgent = wall, urgent
        self._shown_version = model.version
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
        render = getattr(self.app, "render_now", None)
        if render is not None:
            self.app.call_later(render)

    def urgent(self, model: Model) -> object:
        return None

    def render_model(self, model: Model, now: float) -> RenderableType:
        raise NotImplementedError
