"""Streaming, exact statistics of the numeric fields of bags (``bagkit stats summary``).

``Moments`` is the running statistics of any stream of numeric rows (fed in batches).
"""

from __future__ import annotations

from bagkit.stats.accumulate import value_stats
from bagkit.stats.errors import NothingToSummarizeError, StatsError, UnknownTopicError
from bagkit.stats.moments import Moments
from bagkit.stats.result import FieldStats, Summary, TopicStats
from bagkit.stats.summary import summarize

__all__ = [
    "FieldStats",
    "Moments",
    "NothingToSummarizeError",
    "StatsError",
    "Summary",
    "TopicStats",
    "UnknownTopicError",
    "summarize",
    "value_stats",
]
