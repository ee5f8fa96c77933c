"""The lessons on screen: the caption line (what happens now and why) and the summary after an attempt.

- ``LessonBar``: one or two lines under the banner while a lesson, "show me" or the demo runs: the lesson and its
  step (with the hold's progress), or the autopilot's caption. Hidden when nothing runs. The app sets ``text``.
- ``SummaryScreen``: the attempt's score, the best so far, whether it passed, what went wrong, the lesson's one
  line of advice, and a plot of the attempt (height against time, the box's band, green inside it). Its buttons
  post the choice back (``dismiss``): "again", "show", "next" or "close" (keys r, s, n, x). The pilot's keys stay
  live underneath (priority bindings): PANIC always works.
"""

from __future__ import annotations

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widget import Widget
from textual.widgets import Button, Static

from term.lessons.engine import Result
from term.lessons.observe import Box
from term.lessons.progress import LessonProgress
from term.ui.widgets.room import BOX_IN, BOX_OUT, Canvas

PLOT_SIZE = (64, 8)  # cells of the attempt's plot


class LessonBar(Widget):
    """The caption line (module docstring)."""

    DEFAULT_CSS = """
    LessonBar { height: 2; padding: 0 1; background: $boost; color: $text; display: none; }
    LessonBar.running { display: block; }
    """

    def __init__(self, *, id: str | None = None) -> None:  # noqa: A002
        super().__init__(id=id)
        self.text = ""

    def show_text(self, text: str) -> None:
        if text != self.text:
            self.text = text
            self.set_class(bool(text), "running")
            self.refresh()

    def render(self) -> Text:
        return Text(self.text, style="bold")


def attempt_plot(result: Result, box: Box | None, cols: int = PLOT_SIZE[0], rows: int = PLOT_SIZE[1]) -> Text:
    """Height against time over the attempt, the box's band dashed: green where the craft was in the box."""
    trace = result.trace
    if not trace:
        return Text("(no truth samples: nothing to plot)", style="dim")
    t_end = max(trace[-1][0], 1.0)
    h_max = max(2.0, max(p[1] for p in trace) + 0.3, box.high + 0.3 if box is not None else 0.0)
    label_w = 6
    c = Canvas(cols - label_w, rows)
    wx, wy = 2 * c.cols - 1, 4 * c.rows - 1

    def dot(t: float, h: float) -> tuple[int, int]:
        return round(t / t_end * wx), round((1.0 - h / h_max) * wy)

    if box is not None:
        for level in (box.low, box.high):
            x0, y = dot(0.0, level)
            x1, _ = dot(t_end, level)
            c.line(x0, y, x1, y, "grey50", dash=2)
    for t, h, _n, _e, inside in trace:
        c.set(*dot(t, max(0.0, h)), BOX_IN if inside else BOX_OUT)
    out = Text()
    for r in range(rows):
        label = f"{h_max:4.1f}m " if r == 0 else ("  0 m " if r == rows - 1 else " " * label_w)
        out.append(label, style="dim")
        out.append_text(c.row(r))
        out.append("\n")
    out.append(" " * label_w + "0 s".ljust(c.cols - 8) + f"{t_end:5.0f} s", style="dim")
    return out


class SummaryScreen(ModalScreen[str]):
    """After an attempt (module docstring). ``shown``: the autopilot flew it ("show me": not the pilot's score)."""

    DEFAULT_CSS = """
    SummaryScreen { align: center middle; }
    SummaryScreen > Vertical { width: 84; height: auto; max-height: 95%; border: thick $accent; background: $surface;
                               padding: 0 2; }
    SummaryScreen #summary-head { margin: 1 0 0 0; }
    SummaryScreen #summary-plot { margin: 1 0; }
    SummaryScreen Horizontal { height: auto; margin: 1 0 0 0; }
    SummaryScreen Button { margin: 0 2 0 0; min-width: 14; }
    """
    CANCEL = "close"  # what Esc answers (in SAFE, term/ui/app.py)
    BINDINGS = [("r", "choose('again')", "again"), ("s", "choose('show')", "show me"),
                ("n", "choose('next')", "next lesson"), ("x", "choose('close')", "close")]

    def __init__(self, result: Result, title: str, progress: LessonProgress, box: Box | None, *,
                 shown: bool = False, has_next: bool = True) -> None:
        super().__init__()
        self.result = result
        self.title_text = title
        self.progress = progress
        self.box = box
        self.shown = shown
        self.has_next = has_next

    def head(self) -> Text:
        r = self.result
        t = Text()
        verdict = "passed" if r.passed else "not passed"
        t.append(f"{r.score}/100  ", style="bold " + ("green" if r.passed else "yellow"))
        t.append(verdict, style="bold")
        if self.shown:
            t.append("   (flown by the autopilot: not counted in your progress)", style="dim")
        else:
            p = self.progress
            t.append(f"   best {p.best}/100 · {p.attempts} attempt{'s' if p.attempts != 1 else ''}", style="dim")
        t.append(f"\n{r.duration:.0f} s; {r.steps_done} of the lesson's steps done\n\n")
        t.append("What went wrong\n", style="bold")
        for line in r.lines:
            t.append(f"  • {line}\n")
        if r.advice:
            t.append("\n")
            t.append(r.advice, style="italic")
        return t

    def compose(self) -> ComposeResult:
        with Vertical() as v:
            v.border_title = self.title_text
            yield Static(self.head(), id="summary-head")
            yield Static(attempt_plot(self.result, self.box), id="summary-plot")
            with Horizontal():
                yield Button("Again (r)", id="again", variant="primary")
                yield Button("Show me (s)", id="show")
                if self.has_next:
                    yield Button("Next lesson (n)", id="next")
                yield Button("Close (x)", id="close")

    def on_mount(self) -> None:
        self.query_one("#again", Button).focus()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        event.stop()
        self.dismiss(event.button.id or "close")

    def action_choose(self, what: str) -> None:
        if what == "next" and not self.has_next:
            return
        self.dismiss(what)
