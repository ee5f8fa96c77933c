"""The one thing every panel shares: it renders itself from the model when the app's render tick asks."""

from __future__ import annotations

from rich.console import RenderableType
from rich.text import Text
from textual.widgets import Static

from term.model import Model


class ModelView(Static):
    """A panel drawn from the ``Model``. The app calls ``show`` at its render rate; widgets never read I/O."""

    # Panels whose text depends on time alone (ages, rates) redraw even when the model did not change.
    TIME_DEPENDENT = False

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self._shown_version = -1
        self._shown: object = None

    def show(self, model: Model, now: float) -> None:
        if not self.TIME_DEPENDENT and model.version == self._shown_version:
            return
        self._shown_version = model.version
        content = self.render_model(model, now)
        # Rich Text compares text and styles: an identical frame is not re-rendered.
        if isinstance(content, Text) and isinstance(self._shown, Text) and content == self._shown:
            return
        self._shown = content
        self.update(content)

    def on_resize(self) -> None:
        self._shown_version = -1  # panels lay themselves out to their size: redraw now, not at the next change
        render = getattr(self.app, "render_now", None)
        if render is not None:
            self.app.call_later(render)

    def render_model(self, model: Model, now: float) -> RenderableType:
        raise NotImplementedError
