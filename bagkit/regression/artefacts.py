"""A failing check's artefacts: ``report.json``, ``report.html`` and one PNG per failing topic."""

from __future__ import annotations

import html
import json
import shutil
from pathlib import Path

from bagkit.bag import BagReader
from bagkit.compare import TopicResult
from bagkit.compare.bags import Sample, events_of, iter_samples
from bagkit.data.plot_png import Layout, Panel, Trace, draw_png
from bagkit.decode import MessageTypes
from bagkit.regression.golden import GoldenCheck
from bagkit.regression.report_html import FieldSeries, render

MAX_PLOTTED_FIELDS = 6


def _plotted_paths(topic: TopicResult) -> list[str]:
    # The scalar numeric fields that failed; arrays and strings are in the verdict table.
    paths = [f.path for f in topic.failed_fields if f.numeric and "[]" not in f.path]
    return paths[:MAX_PLOTTED_FIELDS]


def _values(samples: list[Sample], path: str, t0: int) -> list[tuple[float, float]]:
    return [
        ((s.time_ns - t0) / 1e9, float(s.fields[path]))
        for s in samples
        if isinstance(s.fields.get(path), int | float)
    ]


def _pairs(
    golden: list[tuple[float, float]], candidate: list[tuple[float, float]], by_order: bool
) -> list[tuple[float, float, float]]:
    """The samples the comparison paired: by position for topics matched in order, else by
    equal time (the stamp), at the golden's time."""
    if by_order:
        return [(t, g, c) for (t, g), (_, c) in zip(golden, candidate, strict=False)]
    candidate_at = dict(candidate)
    return [(t, g, candidate_at[t]) for t, g in golden if t in candidate_at]


def _series(
    topic: TopicResult, g_samples: list[Sample], c_samples: list[Sample], t0: int
) -> list[FieldSeries]:
    fields = {f.path: f for f in topic.failed_fields}
    made = []
    for path in [] if topic.matched_by == "event" else _plotted_paths(topic):
        golden, candidate = _values(g_samples, path, t0), _values(c_samples, path, t0)
        pairs = _pairs(golden, candidate, by_order=topic.matched_by == "order")
        made.append(
            FieldSeries(
                topic.topic, path, golden, candidate, pairs, fields[path].atol, fields[path].rtol
            )
        )
    return made


def _topic_samples(bag: BagReader, types: MessageTypes, topic: str) -> list[Sample]:
    return list(iter_samples(bag, topic, types)) if topic in bag.topics else []


def write_failure_artefacts(check: GoldenCheck, folder: Path) -> list[Path]:
    """Write ``report.json``, ``report.html`` and one PNG per failing topic to ``folder``.

    Returns the files written. The folder is emptied first so that it shows one failure.
    """
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    written = [folder / "report.json", folder / "report.html"]
    if check.drift:
        return _drift_artefacts(check, written)
    written[0].write_text(json.dumps(check.report.to_dict(), indent=2) + "\n")
    series: list[FieldSeries] = []
    with BagReader(check.spec.bag) as golden, BagReader(check.candidate) as candidate:
        g_types = MessageTypes.for_bag(golden)
        c_types = MessageTypes.for_bag(candidate)
        t0 = golden.start_ns
        for topic in (t for t in check.report.topics if not t.passed):
            g_samples = _topic_samples(golden, g_types, topic.topic)
            c_samples = _topic_samples(candidate, c_types, topic.topic)
            topic_series = _series(topic, g_samples, c_samples, t0)
            series += topic_series
            png = folder / f"{topic.topic.strip('/').replace('/', '_')}.png"
            _plot_png(topic, topic_series, g_samples=g_samples, c_samples=c_samples, t0=t0, png=png)
            written.append(png)
    written[1].write_text(render(check, series))
    return written


def _drift_artefacts(check: GoldenCheck, written: list[Path]) -> list[Path]:
    """A drifted golden's report: the drift per topic (nothing was run or compared)."""
    drifts = [d.to_dict() for d in check.drift]
    written[0].write_text(json.dumps({"passed": False, "drift": drifts}, indent=2) + "\n")
    items = "".join(
        f"<li><b>{html.escape(d.topic)}</b> ({html.escape(d.type)})<ul>"
        + "".join(f"<li>{html.escape(c)}</li>" for c in d.changes)
        + "</ul></li>"
        for d in check.drift
    )
    name = html.escape(check.spec.name)
    written[1].write_text(
        f"<!doctype html><html><head><meta charset='utf-8'><title>{name}: drift</title></head>"
        f"<body><h1>{name} ({html.escape(check.mode)}): FAIL</h1><p>The golden's message "
        f"definitions differ from the installed ones; nothing was compared.</p>"
        f"<ul id='drift'>{items}</ul><p><code>bagkit golden migrate "
        f"{html.escape(str(check.spec.directory))}</code> rewrites the golden to today's.</p>"
        "</body></html>\n"
    )
    return written


def _plot_png(
    topic: TopicResult,
    series: list[FieldSeries],
    *,
    g_samples: list[Sample],
    c_samples: list[Sample],
    t0: int,
    png: Path,
) -> None:
    def seconds(samples: list[Sample]) -> list[float]:
        return [(s.time_ns - t0) / 1e9 for s in samples]

    if topic.matched_by == "event":
        traces = []
        for samples, label, marker in ((g_samples, "golden", "o"), (c_samples, "candidate", "x")):
            events = events_of(samples)
            names = [f"{e.name} [{e.level}]" for e in events]
            times = [(e.time_ns - t0) / 1e9 for e in events]
            traces.append(Trace(times, names, label, style="none", marker=marker))
        panels = [Panel(f"{topic.topic}: events (name [level])", traces, legend="best")]
        height = 3.5
    elif not series:
        # No failing scalar: the message counts over time show the missing and extra messages.
        traces = [
            Trace(seconds(samples), list(range(len(samples))), label, style=style)
            for samples, label, style in (
                (g_samples, "golden", "-"),
                (c_samples, "candidate", "--"),
            )
        ]
        panels = [Panel(f"{topic.topic} (message count)", traces, legend="upper left")]
        height = 2.8
    else:
        panels = [_field_panel(topic.topic, one) for one in series]
        height = 2.8
    layout = Layout(
        "time since the golden's start (s)",
        width_in=10.0,
        panel_height_in=height,
        margin_height_in=0.0,
        dpi=80,
        share_x=False,
    )
    draw_png(panels, png, layout)


def _field_panel(topic: str, one: FieldSeries) -> Panel:
    """Both bags' values of one failing field, and their difference on the right axis."""
    lines = [
        Trace([t for t, _ in values], [v for _, v in values], label, style=style)
        for values, label, style in (
            (one.golden, "golden", "-"),
            (one.candidate, "candidate", "--"),
        )
    ]
    difference = Trace(
        [t for t, _, _ in one.pairs],
        [c - g for _, g, c in one.pairs],
        "candidate - golden",
        style=":",
        color="tab:red",
    )
    return Panel(
        f"{topic} {one.path}",
        lines,
        legend="upper left",
        twin=[difference],
        twin_label="candidate - golden",
    )
