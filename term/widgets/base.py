"""The one thing every panel shares: it renders itself from the model when the app's render tick asks."""

from __future__ import annotations

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

    def __init__(self, *, id: str | None = None, classes: str | None = None) -> None:  # noqa: A002
        super().__init__(id=id, classes=classes)
        self._shown_version = -1
        self._shown: RenderableType = Text("")

    def show(self, model: Model, now: float) -> None:
        if not self.TIME_DEPENDENT and model.version == self._shown_version:
            return
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
        render = getattr(self.app, "render_now", None)
        if render is not None:
            self.app.call_later(render)

    def render_model(self, model: Model, now: float) -> RenderableType:
        raise NotImplementedError
