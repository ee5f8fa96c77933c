"""The profiling table: one row per board task from its Profile packets (F6 asks the board for them). Its misses
are every deadline miss since the board booted (the events list counts the board's reports of them, at most one
per 10 s while flying: the column says its window so the two never read as the same count)."""

from __future__ import annotations

from rich.console import RenderableType
from rich.table import Table

from term.core.protocol import BOARD_TASKS
from term.session.model import Model
from term.ui.widgets.base import ModelView

# Names of the board's tasks in Profile.task order (the protocol's BOARD_TASKS); unknown ids show their number.
TASK_NAMES: dict[int, str] = dict(enumerate(BOARD_TASKS))


class ProfileTable(ModelView):
    def render_model(self, model: Model, now: float) -> RenderableType:
        table = Table(title="board task profile (µs)", expand=True, title_style="bold")
        for col in ("task", "mean", "p99", "p99.9", "period", "misses since boot"):
            table.add_column(col, justify="left" if col == "task" else "right")
        if not model.profiles:
            table.add_row("press F6 to ask the board", "", "", "", "", "")
        for task, p in sorted(model.profiles.items()):
            table.add_row(TASK_NAMES.get(task, f"task {task}"), str(p.mean_us), str(p.p99_us), str(p.p999_us),
                          str(p.period_us), str(p.misses), style="red" if p.misses else "")
        return table
