"""Series as a self-contained interactive HTML page (plotly, its JavaScript inlined): zoom,
hover, toggling series in the legend; opens with no network access."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from bagkit.data.series import Series, axis_label, decimate
from bagkit.extras import PLOT, require

# Points per series in the page (SVG stays responsive at this size; spikes are kept).
POINTS = 20000
PANEL_HEIGHT_PX = 260


def write_html(series: Sequence[Series], path: Path, *, title: str, absolute: bool = False) -> None:
    """Write the page for ``series`` to ``path``.

    Raises:
        MissingExtraError: plotly (the plot extra) is not installed.
    """
    require(PLOT, "an HTML plot")
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    panels = list(dict.fromkeys(s.key for s in series))
    bags = list(dict.fromkeys(s.bag for s in series))
    figure = make_subplots(
        rows=len(panels),
        cols=1,
        shared_xaxes=True,
        subplot_titles=panels,
        vertical_spacing=min(0.08, 0.3 / len(panels)),
    )
    for row, key in enumerate(panels, start=1):
        members = [s for s in series if s.key == key]
        for s in members:
            times, values = decimate(s.times, s.values, POINTS)
            figure.add_trace(
                go.Scatter(
                    x=times,
                    y=values,
                    mode="lines",
                    name=f"{s.bag}: {key}" if len(bags) > 1 else key,
                    legendgroup=s.bag,
                    line={"width": 1.2, "color": _COLORS[bags.index(s.bag) % len(_COLORS)]},
                    hovertemplate=f"%{{y:.6g}} {s.unit}<extra>{s.bag}</extra>",
                ),
                row=row,
                col=1,
            )
        figure.update_yaxes(title_text=axis_label(members[0]), row=row, col=1)
    figure.update_xaxes(
        title_text="log time (UTC)" if absolute else "time since bag start [s]",
        row=len(panels),
        col=1,
    )
    figure.update_layout(
        title=title,
        height=120 + PANEL_HEIGHT_PX * len(panels),
        hovermode="x unified",
        legend={"groupclick": "toggleitem"},  # a click hides one series, not the whole bag
        template="plotly_white",
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.write_html(path, include_plotlyjs=True, full_html=True, config={"displaylogo": False})


_COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b")
