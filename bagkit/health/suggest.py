"""A starting contract from a good bag (``bagkit check BAG --suggest``), for the user to edit.

What the bag shows, with margins another good run stays inside: each topic with messages is
required with its type; a topic regular enough to have one (``MIN_MESSAGES``) gets a lower
rate bound of half the lowest rate seen over a window of about ``WINDOW_SAMPLES`` periods, and
a longest gap of twice the longest seen (the silence after its last message included, as
``gap`` counts it); each numeric field that varies (stamps aside) gets bounds widened by its
observed span on each side; ``isnan(*)`` must never hold where no NaN was seen. The
contract holds on the bag it comes from (the rate and gap are computed by the evaluator's own
functions).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bagkit.bag import BagReader
from bagkit.bag.storage_files import bag_path
from bagkit.selection.temporal import window_counts
from bagkit.stats.result import FieldStats, TopicStats

MIN_MESSAGES = 10
"""Fewer messages than this (an event topic): the topic is required, nothing more."""
WINDOW_SAMPLES = 10
"""The rate window holds about this many periods (1 s at least)."""
RATE_MARGIN = 0.5
GAP_MARGIN = 2.0
RANGE_MARGIN = 1.0
"""Value bounds: the observed range widened by this share of its span on each side (noise
around a bias that differs from run to run stays inside)."""


@dataclass
class SuggestedTopic:
    """What one topic's contract will say (None: not asserted)."""

    topic: str
    type: str
    rate_min_hz: float | None = None
    window_s: int | None = None
    max_gap_ms: int | None = None
    values: dict[str, tuple[float, float]] = field(default_factory=dict)
    no_nan: bool = False

    def body(self) -> dict[str, object]:
        """The topic's contract as the spec writes it."""
        body: dict[str, object] = {"type": self.type}
        if self.rate_min_hz is not None:
            body["rate"] = {"min": self.rate_min_hz, "over": f"{self.window_s}s"}
        if self.max_gap_ms is not None:
            body["max_gap"] = f"{self.max_gap_ms}ms"
        if self.values:
            body["values"] = {
                path: {"min": lo, "max": hi} for path, (lo, hi) in self.values.items()
            }
        if self.no_nan:
            body["never"] = ["isnan(*)"]
        return body


def suggest_spec(bag: str | Path) -> str:
    """A contract (YAML text, commented) that ``bag`` keeps and a similar run should keep.

    Raises:
        BagError: the bag cannot be read; NothingToSummarizeError: it holds no message.
    """
    header = (
        f"# Suggested by `bagkit check {bag_path(bag).name} --suggest` from what this bag shows:\n"
        "# rate lower bounds at half the lowest seen, gaps at twice the longest, value bounds\n"
        "# widened by their span on each side. Edit it: drop what does not matter, tighten\n"
        "# what does.\n"
    )
    return header + yaml.safe_dump(suggested_contract(bag), sort_keys=False, width=100)


def suggested_contract(bag: str | Path) -> dict[str, Any]:
    """The contract of :func:`suggest_spec` as the document its YAML holds.

    Raises:
        BagError: the bag cannot be read; NothingToSummarizeError: it holds no message.
    """
    from bagkit.stats.summary import summarize

    summary = summarize([bag])
    stats = {t.topic: t for t in summary.topics}
    topics = []
    with BagReader(bag, allow_empty=True) as reader:
        for name, count in sorted(reader.topic_counts.items()):
            if not count:
                continue
            suggested = SuggestedTopic(name, reader.topics[name].type)
            times = reader.index_log_times(name)
            if times is None:
                times = np.fromiter((m.log_time for m in reader.messages(topics=[name])), np.int64)
            if count >= MIN_MESSAGES:
                _timing(suggested, np.sort(times), reader.start_ns, reader.end_ns)
            if name in stats:
                _ranges(suggested, stats[name])
            topics.append(suggested)
    return {"topics": {t.topic: t.body() for t in topics}}


def _timing(topic: SuggestedTopic, times: np.ndarray, start: int, end: int) -> None:
    gaps = np.diff(times)
    longest = max(int(gaps.max()) if len(gaps) else 0, end - int(times[-1]))
    topic.max_gap_ms = max(1, math.ceil(longest * GAP_MARGIN / 1e6))
    mean_period_s = (int(times[-1]) - int(times[0])) / 1e9 / (len(times) - 1)
    window_s = max(1, math.ceil(WINDOW_SAMPLES * mean_period_s))
    window = window_s * 1_000_000_000
    if end - start < 2 * window:
        return
    # The lowest count over the windows the evaluator looks at (t in [start + W, end]).
    points, counts = window_counts(times, window)
    first = np.searchsorted(points, start + window, side="right") - 1
    lowest = int(counts[first]) if first >= 0 else 0
    later = counts[(points > start + window) & (points <= end)]
    if len(later):
        lowest = min(lowest, int(later.min()))
    if lowest > 0:
        topic.rate_min_hz = _round_down(lowest / window_s * RATE_MARGIN)
        topic.window_s = window_s


def _ranges(topic: SuggestedTopic, stats: TopicStats) -> None:
    nan = 0
    for one in stats.fields:
        nan += one.nan_count
        if _bounded(one):
            assert one.min is not None and one.max is not None
            span = float(one.max) - float(one.min)
            topic.values[one.field] = (
                _round_down(float(one.min) - RANGE_MARGIN * span),
                _round_up(float(one.max) + RANGE_MARGIN * span),
            )
    decoded = stats.count > stats.undecodable  # else nothing was seen of its values
    topic.no_nan = bool(stats.fields) and decoded and nan == 0


def _bounded(one: FieldStats) -> bool:
    """Whether a field gets value bounds: it varies, finitely, and is not a time stamp."""
    if one.min is None or one.max is None or "stamp" in one.field.split("."):
        return False
    return math.isfinite(one.min) and math.isfinite(one.max) and one.min != one.max


def _round_down(value: float) -> float:
    return _nice(value, math.floor)


def _round_up(value: float) -> float:
    return _nice(value, math.ceil)


def _nice(value: float, direction: object) -> float:
    """``value`` to 3 significant digits, rounded in ``direction`` (the bound only widens)."""
    if value == 0 or not math.isfinite(value):
        return value
    scale = 10 ** (math.floor(math.log10(abs(value))) - 2)
    rounded = direction(value / scale) * scale  # type: ignore[operator]
    return float(f"{rounded:.3g}")
