"""bagkit's one PNG plotter (matplotlib, Agg): panels stacked over one time axis.

``draw_png`` draws any :class:`Panel` list; ``write_png`` draws ``bagkit plot``'s series (one
panel per ``topic:field``, bags overlaid); the regression artefacts draw golden against
candidate with the same function. matplotlib is imported when a figure is drawn.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np
    from matplotlib.axes import Axes

    from bagkit.data.series import Series

# Points drawn per series: more than a PNG's width can show, far fewer than a long bag holds.
POINTS = 8000


@dataclass(frozen=True, slots=True)
class Trace:
    """One set of points: a line (``style`` "-", "--", ":") or markers only (``style`` "none"
    with a ``marker``). ``y`` may hold strings: one row per distinct string (events)."""

    x: Sequence[float] | np.ndarray
    y: Sequence[float] | Sequence[str] | np.ndarray
    label: str
    style: str = "-"
    marker: str = ""
    color: str | None = None
    linewidth: float | None = None


@dataclass(frozen=True, slots=True)
class Panel:
    """One plot: its traces, and optionally traces on a second y axis at the right (``twin``)."""

    title: str
    traces: Sequence[Trace]
    ylabel: str = ""
    legend: str | None = "upper right"
    twin: Sequence[Trace] = ()
    twin_label: str = ""


@dataclass(frozen=True, slots=True)
class Layout:
    """The figure: the x axis's label, the size of the page and of each panel."""

    xlabel: str
    width_in: float = 11.0
    panel_height_in: float = 2.6
    margin_height_in: float = 0.8
    dpi: int = 100
    share_x: bool = True


def draw_png(panels: Sequence[Panel], path: Path, layout: Layout) -> None:
    """Draw ``panels`` one above the other into ``path`` (its folder is made)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(
        len(panels),
        1,
        sharex=layout.share_x,
        squeeze=False,
        figsize=(layout.width_in, layout.margin_height_in + layout.panel_height_in * len(panels)),
        dpi=layout.dpi,
    )
    for ax, panel in zip(axes[:, 0], panels, strict=True):
        _draw_traces(ax, panel.traces)
        ax.set_title(panel.title, fontsize=9, loc="left")
        ax.set_ylabel(panel.ylabel, fontsize=8)
        ax.grid(True, alpha=0.3)
        if panel.legend is not None:
            ax.legend(fontsize=8, loc=panel.legend)
        if panel.twin:
            twin = ax.twinx()
            _draw_traces(twin, panel.twin)
            twin.set_ylabel(panel.twin_label, color=panel.twin[0].color, fontsize=8)
            twin.legend(fontsize=8, loc="upper right")
    axes[-1][0].set_xlabel(layout.xlabel)
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path)
    plt.close(figure)


def _draw_traces(ax: Axes, traces: Sequence[Trace]) -> None:
    for trace in traces:
        ax.plot(
            trace.x,
            trace.y,
            linestyle=trace.style,
            marker=trace.marker or None,
            color=trace.color,
            linewidth=trace.linewidth,
            label=trace.label,
        )


def write_png(series: Sequence[Series], path: Path, *, absolute: bool = False) -> None:
    """Draw ``series`` into ``path``: one panel per ``topic:field``, bags overlaid."""
    # Here, not above: the regression artefacts draw panels without the bag-reading modules.
    from bagkit.data.series import axis_label, decimate

    keys = list(dict.fromkeys(s.key for s in series))
    bags = list(dict.fromkeys(s.bag for s in series))
    panels = []
    for key in keys:
        members = [s for s in series if s.key == key]
        traces = [
            Trace(
                *decimate(s.times, s.values, POINTS),
                label=s.bag,
                linewidth=0.9,
                color=f"C{bags.index(s.bag)}",
            )
            for s in members
        ]
        legend = "upper right" if len(bags) > 1 else None
        panels.append(Panel(key, traces, ylabel=axis_label(members[0]), legend=legend))
    xlabel = "log time (UTC)" if absolute else "time since bag start [s]"
    draw_png(panels, path, Layout(xlabel))
