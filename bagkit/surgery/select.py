"""Which messages a ``filter`` keeps: topics by the selection vocabulary, a time window.

The rules of ``ros2 bag convert`` (Jazzy) through :class:`~bagkit.selection.topics.TopicSelection`:
a topic passes when it is named in ``topics`` or matches ``regex`` (all topics, hidden ones
too, when neither is given), and is neither named in ``exclude_topics`` nor matched by
``exclude_regex``. Names are absolute (``imu/data`` is ``/imu/data``). Times are those of
:mod:`bagkit.selection.times`, resolved against the input (``--start 10`` is ten seconds after
its first message). Pure: no ROS, no files.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Protocol

from bagkit.bag.latched import LatchedOptions
from bagkit.selection.conditions import Condition
from bagkit.selection.query import Query
from bagkit.selection.times import TimeLike
from bagkit.selection.topics import TopicSelection
from bagkit.selection.windows import TimeRange, Window

if TYPE_CHECKING:
    import numpy as np

_EVERY_TOPIC = TopicSelection(all_topics=True, include_hidden=True)


class PayloadFilter(Protocol):
    """Which messages of a topic pass by their content (``--where``), payloads not decoded
    here: :mod:`bagkit.surgery.content` compiles them)."""

    def mask_records(
        self,
        records: bytes,
        starts: np.ndarray,
        lengths: np.ndarray,
        log_times: np.ndarray | None = None,
    ) -> np.ndarray:
        """Whether each payload at ``starts``/``lengths`` (logged at ``log_times``) in a
        chunk's records passes."""

    @property
    def problem(self) -> str | None:
        """What could not be matched (undecodable messages, dropped), or None."""


@dataclass(frozen=True)
class Selection:
    """The topics to keep, the time range as given, and (once resolved) its log-time window.

    Attributes:
        latched: the latched state written before a window's start (see
            :mod:`bagkit.bag.latched`): on by default.
        where: the condition the messages of the topics that have its fields must satisfy
            (``--where``), compiled against the inputs into ``content`` by
            :func:`bagkit.surgery.content.with_content`.
        where_topic: the one topic ``where`` applies to (``--where 'TOPIC: CONDITION'``);
            None: every selected topic that has its fields.
        state_topics: topics whose messages hold until the next one, for a condition over
            time (as transient-local topics do).
        content: topics whose messages pass only when their filter says so.
    """

    topics: TopicSelection = _EVERY_TOPIC
    span: TimeRange = field(default_factory=TimeRange)
    window: Window = field(default_factory=Window)
    latched: LatchedOptions = field(default_factory=LatchedOptions)
    where: Condition | None = None
    where_topic: str | None = None
    state_topics: frozenset[str] = frozenset()
    content: Mapping[str, PayloadFilter] = field(default_factory=dict)

    @classmethod
    def create(  # noqa: PLR0917 (the options of ``bagkit filter``, in its order)
        cls,
        topics: Iterable[str] = (),
        regex: str = "",
        exclude_topics: Iterable[str] = (),
        exclude_regex: str = "",
        start: TimeLike | None = None,
        end: TimeLike | None = None,
    ) -> Selection:
        """A selection from ``bagkit filter``'s options.

        Raises:
            SelectionError: a regex does not compile, a time does not parse, or the range
                is empty.
        """
        named = list(topics)
        return cls(
            TopicSelection.create(
                named,
                all_topics=not named and not regex,
                regex=regex or None,
                exclude=exclude_regex or None,
                include_hidden=True,
                exclude_topics=exclude_topics,
            ),
            TimeRange.parse(start, end),
        )

    @classmethod
    def of(
        cls,
        query: Query,
        *,
        regex: str = "",
        exclude_topics: Iterable[str] = (),
        exclude_regex: str = "",
    ) -> Selection:
        """A selection of ``query``'s topics (a service by its name), time range and condition,
        with ``bagkit filter``'s topic rules beside it (``--regex``, exclusions).

        Raises:
            SelectionError: a regex does not compile.
        """
        topics = cls.create(query.topics, regex, exclude_topics, exclude_regex).topics
        return cls(topics, query.span, where=query.where)

    def resolved(self, start_ns: int, end_ns: int) -> Selection:
        """This selection with its window resolved against messages spanning the two times."""
        return replace(self, window=self.span.resolve(start_ns, end_ns))

    def topic_passes(self, topic: str) -> bool:
        """Whether messages of ``topic`` are kept (time aside)."""
        return self.topics.matches(topic)

    def time_passes(self, log_time: int) -> bool:
        """Whether a message logged at ``log_time`` is in the window."""
        return self.window.contains(log_time)

    def covers(self, start: int, end: int) -> bool:
        """Whether every log time in ``[start, end]`` is in the window."""
        return self.window.covers(start, end)
