"""A failing check's artefacts: ``report.json``, ``report.html`` and one PNG per failing topic."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from bagkit.bag import BagReader
from bagkit.compare import TopicResult
from bagkit.compare.bags import Sample, events_of, iter_samples
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
    written[0].write_text(json.dumps(check.report.to_dict(), indent=2) + "\n")
    series: list[FieldSeries] = []
    with BagReader(check.spec.bag) as golden, BagReader(check.candidate) as candidate:
        g_types = MessageTypes.from_definitions(golden.definitions)
        c_types = MessageTypes.from_definitions(candidate.definitions)
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


def _plot_png(
    topic: TopicResult,
    series: list[FieldSeries],
    *,
    g_samples: list[Sample],
    c_samples: list[Sample],
    t0: int,
    png: Path,
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if topic.matched_by == "event":
        fig, ax = plt.subplots(figsize=(10, 3.5))
        for samples, label, marker in ((g_samples, "golden", "o"), (c_samples, "candidate", "x")):
            events = events_of(samples)
            ax.scatter(
                [(e.time_ns - t0) / 1e9 for e in events],
                [f"{e.name} [{e.level}]" for e in events],
                marker=marker,
                label=label,
            )
        ax.set_title(f"{topic.topic}: events (name [level])")
        ax.legend()
        ax.set_xlabel("time since the golden's start (s)")
    elif not series:
        # No failing scalar: the message counts over time show the missing and extra messages.
        fig, ax = plt.subplots(figsize=(10, 2.8))
        for samples, label, style in ((g_samples, "golden", "-"), (c_samples, "candidate", "--")):
            times = [(s.time_ns - t0) / 1e9 for s in samples]
            ax.plot(times, range(len(times)), style, label=label)
        ax.set_title(f"{topic.topic} (message count)", fontsize=9)
        ax.legend(fontsize=8, loc="upper left")
        ax.set_xlabel("time since the golden's start (s)")
    else:
        fig, axes = plt.subplots(len(series), 1, figsize=(10, 2.8 * len(series)), squeeze=False)
        for ax, one in zip(axes[:, 0], series, strict=True):
            for values, label, style in (
                (one.golden, "golden", "-"),
                (one.candidate, "candidate", "--"),
            ):
                ax.plot([t for t, _ in values], [v for _, v in values], style, label=label)
            diff_ax = ax.twinx()
            diff_ax.plot(
                [t for t, _, _ in one.pairs],
                [c - g for _, g, c in one.pairs],
                ":",
                color="tab:red",
                label="candidate - golden",
            )
            diff_ax.set_ylabel("candidate - golden", color="tab:red", fontsize=8)
            diff_ax.legend(fontsize=8, loc="upper right")
            ax.set_title(f"{topic.topic} {one.path}", fontsize=9)
            ax.legend(fontsize=8, loc="upper left")
        axes[-1, 0].set_xlabel("time since the golden's start (s)")
    fig.tight_layout()
    fig.savefig(png, dpi=80)
    plt.close(fig)
