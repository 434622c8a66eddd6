"""``bagkit check --html``: the checked bags as one self-contained page (plotly inlined once).

Per bag its verdict and a table of the assertions; per broken assertion a plot over time
with each span where it broke shaded: the fields its condition reads (those holding a NaN for
``isnan(*)``), or for ``gap``/``rate`` the time between consecutive messages. Under each plot,
where it first broke, the commands that replay or cut it and, where bags are served, a link
to Foxglove at that moment.
"""

from __future__ import annotations

import html
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from bagkit.bag import BagReader
from bagkit.data.errors import DataError
from bagkit.data.series import Series, axis_label, decimate, load_series
from bagkit.extras import PLOT, require
from bagkit.health.verdicts import Assertion, CheckResult, HealthReport
from bagkit.selection.condition_terms import (
    Check,
    Comparison,
    Delta,
    Unchanged,
    path_text,
    walk,
)
from bagkit.selection.conditions import parse_condition
from bagkit.selection.errors import SelectionError

if TYPE_CHECKING:
    import plotly.graph_objects as go

POINTS = 5000
MAX_SERIES = 4
"""Fields in one plot at most (``isnan(*)`` over a wide message)."""
MAX_SPANS = 200
"""Shaded spans in one plot at most (the first ones)."""
STYLE = """
body{font:14px system-ui,sans-serif;margin:24px;color:#222}
h1{font-size:20px}h2{font-size:16px;margin-top:28px}h3{font-size:14px;margin-bottom:2px}
table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left}
.fail{color:#b00020;font-weight:600}.pass{color:#1b7f3b}pre{background:#f6f6f6;padding:6px}
"""


def write_report(result: CheckResult, path: Path) -> None:
    """Write the page for ``result`` to ``path``.

    Raises:
        MissingExtraError: plotly (the plot extra) is not installed.
    """
    require(PLOT, "an HTML report")
    parts = [f"<h1>bagkit check: {_verdict(result.passed)}</h1>"]
    first_plot = True
    for report in result.reports:
        parts.append(f"<h2>{html.escape(report.bag)}: {_verdict(report.passed)}</h2>")
        if report.error is not None:
            parts.append(f"<p class='fail'>not read: {html.escape(report.error)}</p>")
            continue
        parts.append(_table(report))
        for assertion in report.broken:
            parts.append(f"<h3 class='fail'>{html.escape(assertion.topic)}: ")
            parts.append(f"{html.escape(assertion.what)}</h3>")
            parts.append(f"<p>{html.escape(assertion.summary(report.start_ns))}</p>")
            figure = _figure(report, assertion)
            if figure is not None:
                parts.append(
                    figure.to_html(
                        full_html=False,
                        include_plotlyjs=first_plot,
                        config={"displaylogo": False},
                    )
                )
                first_plot = False
            commands = assertion.commands(report.bag, report.start_ns)
            if commands:
                parts.append(f"<pre>{html.escape(chr(10).join(commands))}</pre>")
            link = report.link(assertion)
            if link is not None:
                parts.append(f"<p><a href='{html.escape(link)}'>open in Foxglove</a></p>")
    page = (
        "<!DOCTYPE html><html><head><meta charset='utf-8'><title>bagkit check</title>"
        f"<style>{STYLE}</style></head><body>{''.join(parts)}</body></html>\n"
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(page)


def _verdict(passed: bool) -> str:
    return "<span class='pass'>healthy</span>" if passed else "<span class='fail'>broken</span>"


def _table(report: HealthReport) -> str:
    rows = "".join(
        f"<tr><td>{html.escape(a.topic)}</td><td>{html.escape(a.what)}</td>"
        f"<td class='{'pass' if a.passed else 'fail'}'>{'pass' if a.passed else 'FAIL'}</td>"
        f"<td>{html.escape(a.reason)}</td><td>{len(a.spans) or ''}</td></tr>"
        for a in report.assertions
    )
    return (
        "<table><tr><th>topic</th><th>assertion</th><th></th><th>why</th><th>times</th></tr>"
        f"{rows}</table>"
    )


def _figure(report: HealthReport, assertion: Assertion) -> go.Figure | None:
    """The plot of one broken assertion with its spans shaded (None: nothing to plot)."""
    if not assertion.is_condition:
        return None
    import plotly.graph_objects as go

    series = _series(report, assertion)
    figure = go.Figure()
    for one in series:
        times, values = decimate(one.times, one.values, POINTS)
        figure.add_trace(go.Scatter(x=times, y=values, mode="lines+markers", name=one.field))
    # A span of one message has no width: shade at least a few pixels' worth of the bag.
    width = max((float(one.times[-1]) for one in series if len(one.times)), default=1.0) / 400
    for start, end, _ in assertion.spans[:MAX_SPANS].tolist():
        x0, x1 = (start - report.start_ns) / 1e9, (end - report.start_ns) / 1e9
        if x1 - x0 < width:
            x0, x1 = x0 - width / 2, x1 + width / 2
        figure.add_vrect(x0=x0, x1=x1, fillcolor="#d62728", opacity=0.25, line_width=0)
    label = axis_label(series[0]) if len(series) == 1 else "value"
    figure.update_layout(
        height=300,
        margin={"t": 30, "b": 40},
        template="plotly_white",
        xaxis_title="time since bag start [s]",
        yaxis_title=label,
    )
    return figure


def _series(report: HealthReport, assertion: Assertion) -> list[Series]:
    """What to plot for ``assertion``: its fields, or the time between messages."""
    tree = parse_condition(assertion.what).tree
    fields, any_leaf = [], False
    for node in walk(tree):
        if isinstance(node, Comparison | Delta):
            fields.append(path_text(node.path))
        elif isinstance(node, Check | Unchanged):
            if node.path is None:
                any_leaf = True
            else:
                fields.append(path_text(node.path))
    wanted = [*dict.fromkeys(fields)] or (["*"] if any_leaf else [])
    found: list[Series] = []
    if wanted:
        specs = [f"{assertion.topic}:{field.replace('[*]', '[]')}" for field in wanted]
        try:
            found = load_series([report.bag], specs)
        except (DataError, SelectionError):
            found = []
        if any_leaf and not fields:
            with_nan = [s for s in found if np.isnan(s.values).any()]
            found = with_nan or [s for s in found if np.ptp(s.values) > 0]
    return found[:MAX_SERIES] or [_intervals(report, assertion.topic)]


def _intervals(report: HealthReport, topic: str) -> Series:
    """The time from each message of ``topic`` to the one before it (ms)."""
    with BagReader(report.bag, allow_empty=True) as reader:
        times = reader.index_log_times(topic)
        if times is None:
            times = np.fromiter((m.log_time for m in reader.messages(topics=[topic])), np.int64)
    seconds = (times[1:] - report.start_ns) / 1e9
    return Series(
        report.bag, topic, "time since the previous message", "ms", seconds, np.diff(times) / 1e6
    )
