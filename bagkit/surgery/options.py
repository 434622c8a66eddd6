"""What a rewrite is asked (:class:`OutputOptions`, the selection resolved against its
inputs) and what it reports (:class:`RewriteReport`): shared by the chunk copy
(:mod:`~bagkit.surgery.rewrite`) and the message copy (:mod:`~bagkit.surgery.message_copy`)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from bagkit.bag.messages import TopicInfo
from bagkit.selection.topics import require_topics
from bagkit.selection.windows import outside_warning
from bagkit.surgery.select import Selection

if TYPE_CHECKING:
    import numpy as np


@dataclass
class RewriteReport:
    """What a rewrite wrote, and what it could not read.

    Attributes:
        output: the bag written.
        files: its storage files.
        input_messages: messages the inputs' indexes (or salvage) counted.
        topic_counts: messages written per topic (the latched state's included).
        latched_messages: messages of the latched state written before the window.
        chunks_copied: chunks copied as they were stored.
        problems: what was lost or could not be read, one line each.
        warnings: what the user should know that lost nothing (a time window outside the
            inputs).
    """

    output: Path
    files: list[Path] = field(default_factory=list)
    input_messages: int = 0
    topic_counts: dict[str, int] = field(default_factory=dict)
    chunks_copied: int = 0
    latched_messages: int = 0
    problems: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    @property
    def message_count(self) -> int:
        """Messages written."""
        return sum(self.topic_counts.values())

    @property
    def recover_exit_code(self) -> int:
        """``bagkit recover``'s status: 0 all read (an intact bag without messages too), 3
        recovered with a loss (``problems``), 1 nothing recovered of what was lost."""
        if not self.message_count and self.problems:
            return 1
        return 3 if self.problems else 0

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form."""
        return {
            "output": str(self.output),
            "files": [str(f) for f in self.files],
            "input_messages": self.input_messages,
            "message_count": self.message_count,
            "topic_counts": self.topic_counts,
            "chunks_copied": self.chunks_copied,
            "latched_messages": self.latched_messages,
            "problems": self.problems,
            "warnings": self.warnings,
        }


@dataclass
class OutputOptions:
    """How the output is written (see :class:`~bagkit.surgery.output.OutputBag`).

    Attributes:
        storage: ``mcap`` or ``sqlite3`` (:mod:`~bagkit.surgery.sqlite3_output`).
        compression_mode: sqlite3 only: rosbag2's ``message`` or ``file`` zstd compression
            (``compression`` zstd); MCAP compresses chunks.
    """

    compression: str = "zstd"
    max_bag_size: int = 0
    max_bag_duration_s: float = 0
    force: bool = False
    check_crc: bool = True
    storage: str = "mcap"
    compression_mode: str = "message"


def stored_names(selection: Selection, names: Iterable[str]) -> Selection:
    """The selection's named topics as the inputs (their topic ``names``) store them: a
    service's name is its event topic, as in echo.

    Raises:
        UnknownTopicError: a named topic (``--latched-topics`` too, used or not) is in no
            input (the message names the closest).
    """
    names = set(names)
    require_topics(selection.latched.extra_topics, names)
    stored = frozenset(require_topics(sorted(selection.topics.topics), names))
    return replace(selection, topics=replace(selection.topics, topics=stored))


def resolve(
    selection: Selection,
    bags: Sequence[Path],
    names: set[str],
    spans: list[tuple[int, int]],
    report: RewriteReport,
) -> Selection:
    """The selection's named topics checked against the inputs' topic ``names``, its times
    against their ``spans``; a window outside them is a warning in ``report``.

    Raises:
        UnknownTopicError: a named topic (``--latched-topics`` too, used or not) is in no
            input (the message names the closest).
    """
    selection = stored_names(selection, names)
    if not spans or not selection.span.bounded:
        return selection
    first, last = min(s for s, _ in spans), max(e for _, e in spans)
    resolved = selection.resolved(first, last)
    label = ", ".join(str(bag) for bag in bags)
    outside = outside_warning(label, resolved.window, first, last)
    if outside is not None:
        report.warnings.append(outside)
    return resolved


class TopicRewrite(Protocol):
    """A topic whose payloads are rewritten on the way (``bagkit migrate``)."""

    @property
    def topic(self) -> TopicInfo:
        """The topic as the output lists it."""

    @property
    def definition(self) -> str:
        """The definition the output stores for it."""

    def payload(self, data: bytes) -> bytes:
        """One payload as written to the output."""

    def payloads(
        self, buf: np.ndarray, starts: np.ndarray, lengths: np.ndarray, room: int
    ) -> list[tuple[np.ndarray, np.ndarray]]:
        """The payloads at ``starts``/``lengths`` of a chunk's records ``buf`` (uint8), as
        written to the output: groups ``(indexes, rows)``, ``rows[i]`` (a row of a 2-D uint8
        array) ``room`` bytes for the caller then the payload at ``indexes[i]``, every index
        once."""


@dataclass(frozen=True)
class PayloadRewrites:
    """Topics rewritten on the way, and ``custom_data`` entries the output gains."""

    topics: Mapping[str, TopicRewrite] = field(default_factory=dict)
    custom_data: Mapping[str, str] = field(default_factory=dict)
