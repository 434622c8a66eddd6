"""``report.html``: a failing check as one self-contained page (inline CSS and SVG, no network).

The page holds the verdict table (every output topic: counts, missing, extra, the failing
fields with their largest errors), and per failing numeric field two plots over time: golden
and candidate with the tolerance band around the golden, and candidate - golden with the band
around zero. Event topics (diagnostics) list their first divergences.
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from dataclasses import dataclass

from bagkit.compare import TopicResult
from bagkit.regression.golden import GoldenCheck

MAX_POINTS = 1500
WIDTH = 900
HEIGHT = 200
MARGIN = 56

GOLDEN_COLOR = "#1f77b4"
CANDIDATE_COLOR = "#ff7f0e"
DIFF_COLOR = "#d62728"
BAND_COLOR = "#2ca02c"

STYLE = """
body{font:14px system-ui,sans-serif;margin:24px;color:#222}
h1{font-size:20px}h2{font-size:16px;margin-top:28px}h3{font-size:14px}
table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left}
.fail{color:#b00020;font-weight:600}.pass{color:#1b7f3b}
svg{background:#fafafa;border:1px solid #ddd;margin:4px 0}
.legend span{margin-right:16px}.mono{font-family:monospace}
"""


@dataclass(frozen=True, slots=True)
class FieldSeries:
    """One failing field of one topic: both bags' values over time (seconds), the matched
    pairs ``(time, golden, candidate)`` as the comparison paired them, the tolerance."""

    topic: str
    path: str
    golden: list[tuple[float, float]]
    candidate: list[tuple[float, float]]
    pairs: list[tuple[float, float, float]]
    atol: float
    rtol: float

    def bound(self, golden: float, candidate: float = 0.0) -> float:
        """The largest accepted |candidate - golden| (as ``Tolerance.accepts`` reads it)."""
        return max(self.atol, self.rtol * max(abs(golden), abs(candidate)))


def _thin(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    step = max(1, math.ceil(len(points) / MAX_POINTS))
    return points[::step]


class _Axes:
    """Maps data to SVG coordinates."""

    def __init__(self, xs: Sequence[float], ys: Sequence[float]) -> None:
        finite = [y for y in ys if math.isfinite(y)] or [0.0]
        self.x0, self.x1 = (min(xs), max(xs)) if xs else (0.0, 1.0)
        self.y0, self.y1 = min(finite), max(finite)
        if self.x1 == self.x0:
            self.x1 = self.x0 + 1.0
        if self.y1 == self.y0:
            pad = abs(self.y0) * 1e-3 or 1.0
            self.y0, self.y1 = self.y0 - pad, self.y1 + pad

    def x(self, value: float) -> float:
        return MARGIN + (value - self.x0) / (self.x1 - self.x0) * (WIDTH - MARGIN - 10)

    def y(self, value: float) -> float:
        clipped = min(max(value, self.y0), self.y1) if math.isfinite(value) else self.y0
        return HEIGHT - 24 - (clipped - self.y0) / (self.y1 - self.y0) * (HEIGHT - 34)

    def polyline(self, points: list[tuple[float, float]], color: str, css: str) -> str:
        coords = " ".join(f"{self.x(t):.1f},{self.y(v):.1f}" for t, v in _thin(points))
        return f'<polyline class="{css}" fill="none" stroke="{color}" points="{coords}"/>'

    def band(self, upper: list[tuple[float, float]], lower: list[tuple[float, float]]) -> str:
        outline = [*_thin(upper), *reversed(_thin(lower))]
        coords = " ".join(f"{self.x(t):.1f},{self.y(v):.1f}" for t, v in outline)
        return (
            f'<polygon class="band" fill="{BAND_COLOR}" fill-opacity="0.18" stroke="none" '
            f'points="{coords}"/>'
        )

    def frame(self, title: str) -> str:
        ticks = "".join(
            f'<text x="4" y="{self.y(v) + 4:.1f}" font-size="10">{v:.4g}</text>'
            for v in (self.y0, (self.y0 + self.y1) / 2, self.y1)
        )
        return (
            f'<text x="{MARGIN}" y="12" font-size="12">{html.escape(title)}</text>{ticks}'
            f'<text x="{MARGIN}" y="{HEIGHT - 6}" font-size="10">{self.x0:.2f} s</text>'
            f'<text x="{WIDTH - 70}" y="{HEIGHT - 6}" font-size="10">{self.x1:.2f} s</text>'
        )


def _svg(body: str, label: str) -> str:
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" '
        f'role="img" aria-label="{html.escape(label)}" class="plot">{body}</svg>'
    )


def field_plots(series: FieldSeries) -> str:
    """Golden vs candidate with the tolerance band, and their difference with the band."""
    golden, candidate = series.golden, series.candidate
    upper = [(t, v + series.bound(v)) for t, v in golden]
    lower = [(t, v - series.bound(v)) for t, v in golden]
    values = [v for _, v in golden + candidate] + [v for _, v in upper + lower]
    axes = _Axes([t for t, _ in golden + candidate], values)
    values_svg = _svg(
        axes.frame(f"{series.topic} {series.path}: golden, candidate, tolerance band")
        + axes.band(upper, lower)
        + axes.polyline(golden, GOLDEN_COLOR, "golden")
        + axes.polyline(candidate, CANDIDATE_COLOR, "candidate"),
        f"{series.topic} {series.path} values",
    )
    diff = [(t, c - g) for t, g, c in series.pairs]
    bounds = [(t, series.bound(g, c)) for t, g, c in series.pairs]
    diff_axes = _Axes(
        [t for t, _ in diff],
        [d for _, d in diff] + [b for _, b in bounds] + [-b for _, b in bounds],
    )
    diff_svg = _svg(
        diff_axes.frame(f"{series.path}: candidate - golden, tolerance band")
        + diff_axes.band(bounds, [(t, -b) for t, b in bounds])
        + diff_axes.polyline(diff, DIFF_COLOR, "difference"),
        f"{series.topic} {series.path} difference",
    )
    return values_svg + diff_svg


def _verdict_row(topic: TopicResult) -> str:
    fields = ", ".join(
        f"{html.escape(f.path)} (max |err| {f.max_abs_error:.3g}, tol {f.atol:g}/{f.rtol:g})"
        for f in topic.failed_fields
    )
    verdict = '<span class="pass">pass</span>' if topic.passed else '<span class="fail">FAIL</span>'
    cells = [
        html.escape(topic.topic),
        verdict,
        topic.matched_by or "-",
        str(topic.golden_count),
        str(topic.candidate_count),
        str(topic.missing),
        str(topic.extra),
        fields or "-",
    ]
    return "<tr>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>"


def _divergences(topic: TopicResult) -> str:
    if not topic.divergences:
        return ""
    rows = "".join(f"<li class='mono'>{html.escape(d.describe())}</li>" for d in topic.divergences)
    return f"<h3>first divergences</h3><ul>{rows}</ul>"


def render(check: GoldenCheck, series: Sequence[FieldSeries]) -> str:
    """The whole page."""
    report = check.report
    header = "".join(
        f"<th>{h}</th>"
        for h in ("topic", "verdict", "matched by", "golden", "candidate", "missing", "extra")
    )
    table = (
        f"<table id='verdict'><tr>{header}<th>failing fields</th></tr>"
        + "".join(_verdict_row(t) for t in report.topics)
        + "</table>"
    )
    sections = []
    for topic in (t for t in report.topics if not t.passed):
        plots = "".join(field_plots(s) for s in series if s.topic == topic.topic)
        sections.append(
            f"<section class='topic'><h2>{html.escape(topic.topic)}</h2>"
            f"{plots}{_divergences(topic)}</section>"
        )
    legend = (
        f"<p class='legend'><span style='color:{GOLDEN_COLOR}'>&#9632; golden</span>"
        f"<span style='color:{CANDIDATE_COLOR}'>&#9632; candidate</span>"
        f"<span style='color:{DIFF_COLOR}'>&#9632; candidate - golden</span>"
        f"<span style='color:{BAND_COLOR}'>&#9632; tolerance band</span>"
        "<br>time in seconds since the golden's start</p>"
    )
    verdict = "pass" if report.passed else "FAIL"
    title = f"{check.spec.name} ({check.mode}): {verdict}"
    return (
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
        f"<title>{html.escape(title)}</title><style>{STYLE}</style></head><body>"
        f"<h1>{html.escape(title)}</h1>"
        f"<p class='mono'>golden {html.escape(report.golden)}<br>"
        f"candidate {html.escape(report.candidate)}</p>"
        f"{table}{legend}{''.join(sections)}</body></html>\n"
    )
