"""What :func:`bagkit.stats.summarize` returns: per-field, per-topic and overall results."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import pandas as pd


@dataclass(frozen=True, slots=True)
class FieldStats:
    """Statistics of one numeric leaf field (NaN values are counted apart, as pandas does).

    ``min``/``max``/``mean`` are None without values, ``std`` (ddof=1) below two values;
    ``min``/``max`` are ints for integer and boolean fields.
    """

    field: str
    count: int
    nan_count: int
    min: float | int | None
    max: float | int | None
    mean: float | None
    std: float | None


@dataclass(frozen=True, slots=True)
class TopicStats:
    """Count, rate and field statistics of one topic.

    ``rate_hz`` is (count - 1) / (last - first log time), None below two messages.
    ``undecodable``: messages counted in ``count`` whose payload did not decode (left out of
    the field statistics).
    """

    topic: str
    type: str
    count: int
    rate_hz: float | None
    fields: tuple[FieldStats, ...]
    undecodable: int = 0


@dataclass(frozen=True, slots=True)
class Summary:
    """What :func:`summarize` found.

    Attributes:
        bags: the bags summarized, as given.
        start_ns, end_ns: first and last log time of the summarized messages (None when the
            time window held none).
        topics: per topic, in name order.
        skipped: topic -> why it could not be decoded (not in ``topics``).
        problems: what could not be read (salvaged files, messages that do not decode).
        unread: the bags that could not be read at all (among others: in ``problems`` too).
    """

    bags: tuple[str, ...]
    start_ns: int | None
    end_ns: int | None
    topics: tuple[TopicStats, ...]
    skipped: dict[str, str] = field(default_factory=dict)
    problems: tuple[str, ...] = ()
    unread: tuple[str, ...] = ()

    @property
    def duration_s(self) -> float:
        """Seconds from the first to the last summarized message (0 when none)."""
        if self.start_ns is None or self.end_ns is None:
            return 0.0
        return (self.end_ns - self.start_ns) / 1e9

    def to_dict(self) -> dict[str, Any]:
        """The JSON document of ``bagkit stats summary --format json``."""
        return {
            "bags": list(self.bags),
            "unread": list(self.unread),
            "start_ns": self.start_ns,
            "end_ns": self.end_ns,
            "duration_s": self.duration_s,
            "topics": [
                {
                    "topic": t.topic,
                    "type": t.type,
                    "count": t.count,
                    "rate_hz": t.rate_hz,
                    "undecodable": t.undecodable,
                    "fields": [asdict(f) for f in t.fields],
                }
                for t in self.topics
            ],
        }

    def to_dataframe(self) -> pd.DataFrame:
        """One row per (topic, field): columns topic, type, field, count ... std."""
        import pandas as pd

        rows = [
            {"topic": t.topic, "type": t.type, **asdict(f)} for t in self.topics for f in t.fields
        ]
        columns = ["topic", "type", "field", "count", "nan_count", "min", "max", "mean", "std"]
        frame = pd.DataFrame(rows, columns=columns)
        return frame.astype({c: "float64" for c in ("min", "max", "mean", "std")})
