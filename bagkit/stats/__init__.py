"""Streaming, exact statistics of the numeric fields of bags (``bagkit stats summary``)."""

from __future__ import annotations

from bagkit.stats.errors import NothingToSummarizeError, StatsError, UnknownTopicError
from bagkit.stats.result import FieldStats, Summary, TopicStats
from bagkit.stats.summary import summarize

__all__ = [
    "FieldStats",
    "NothingToSummarizeError",
    "StatsError",
    "Summary",
    "TopicStats",
    "UnknownTopicError",
    "summarize",
]
