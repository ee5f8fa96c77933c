"""`term plot LOG.csv -o out.png`: the logged signals, drawn with matplotlib (Agg, no display needed).

Columns in board units (as the log download writes them) are converted for reading: time in s, angles in °,
rates in °/s, accelerations in g, height in m, battery in V. Groups that share a unit share a panel.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

# (title, unit, [(column, scale to the unit)]) per panel.
GROUPS: tuple[tuple[str, str, tuple[tuple[str, float], ...]], ...] = (
    ("attitude", "°", (("phi", 0.01), ("theta", 0.01), ("psi", 0.01))),
    ("body rates", "°/s", (("sp", 1 / 16.4), ("sq", 1 / 16.4), ("sr", 1 / 16.4))),
    ("accelerations", "g", (("sax", 1 / 16384), ("say", 1 / 16384), ("saz", 1 / 16384))),
    ("motors", "0..1000", (("ae1", 1), ("ae2", 1), ("ae3", 1), ("ae4", 1))),
    ("height", "m", (("height", 0.001),)),
    ("pressure", "Pa", (("pressure", 1),)),
    ("battery", "V", (("battery", 0.01),)),
    ("mode", "", (("mode", 1),)),
)


class PlotError(ValueError):
    """The log cannot be drawn; the message is one line."""


def read_log(path: Path) -> dict[str, list[float]]:
    try:
        with path.open(newline="", encoding="utf-8") as f:
            reader = csv.reader(f)
            header = next(reader, None)
            if not header:
                raise PlotError(f"{path} is empty")
            cols: dict[str, list[float]] = {h: [] for h in header}
            for n, row in enumerate(reader, start=2):
                if row and row[0] == header[0] and row == header:
                    continue  # a repeated header (a new segment)
                try:
                    values = [float(v) for v in row]
                except ValueError:
                    raise PlotError(f"{path} line {n}: not numbers ({','.join(row)[:40]}…)") from None
                for h, v in zip(header, values, strict=False):
                    cols[h].append(v)
    except FileNotFoundError:
        raise PlotError(f"{path} not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise PlotError(f"cannot read {path}: {exc}") from None
    if "hex" in cols and "offset" in cols:
        raise PlotError(f"{path} holds raw log bytes (the board's format was not recognised), nothing to plot")
    return cols


def plot_log(path: Path, output: Path, signals: Sequence[str] | None = None) -> Path:
    cols = read_log(path)
    if "t_us" in cols:
        t = [v / 1e6 for v in cols["t_us"]]
        xlabel = "board time (s)"
    else:
        t = list(range(len(next(iter(cols.values())))))
        xlabel = "record"
    if not t:
        raise PlotError(f"{path} has a header but no records")
    if signals:
        unknown = [s for s in signals if s not in cols]
        if unknown:
            raise PlotError(f"no column {unknown[0]!r} in {path}; columns: {', '.join(cols)}")
        panels = [(s, "", ((s, 1.0),)) for s in signals]
    else:
        panels = [g for g in GROUPS if any(c in cols for c, _ in g[2])]
        known = {c for g in GROUPS for c, _ in g[2]} | {"t_us", "segment"}
        panels += [(c, "", ((c, 1.0),)) for c in cols if c not in known]
    if not panels:
        raise PlotError(f"{path}: nothing to plot")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(panels), 1, sharex=True, figsize=(11, 2.0 * len(panels) + 0.6), squeeze=False)
    for ax, (title, unit, series) in zip(axes[:, 0], panels, strict=True):
        for col, scale in series:
            if col in cols:
                ax.plot(t, [v * scale for v in cols[col]], label=col, linewidth=0.9)
        ax.set_ylabel(f"{title}\n({unit})" if unit else title)
        if title == "mode" and "mode" in cols:
            from term.protocol import Mode

            present = sorted({int(v) for v in cols["mode"]} & {int(m) for m in Mode})
            ax.set_yticks(present, [Mode(v).name for v in present])
        ax.grid(True, alpha=0.3)
        if len(series) > 1:
            ax.legend(loc="upper right", fontsize="small", ncol=len(series))
    axes[-1, 0].set_xlabel(xlabel)
    fig.suptitle(f"{path.name}: {len(t)} records")
    fig.tight_layout()
    try:
        output.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(output, dpi=110)
    except (OSError, ValueError) as exc:
        raise PlotError(f"cannot write {output}: {exc}") from None
    finally:
        plt.close(fig)
    return output
