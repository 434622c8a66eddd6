"""A health contract evaluated on one bag: one :class:`Assertion` per line of the contract.

Every assertion over time is a condition that must never hold
(:class:`~bagkit.health.spec.TopicContract`), found with
:func:`bagkit.data.episodes.find_episodes` (numpy over the bag's columns; ``gap`` and ``rate``
from the MCAP indexes alone). A topic the bag lacks, or has no message of, breaks its contract;
a field the topic's type lacks is a bad spec (:class:`SpecError`).
"""

from __future__ import annotations

import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bagkit.bag import BagReader
from bagkit.bag.definitions import canonical_type_name
from bagkit.data.episodes import NO_SPANS, find_episodes
from bagkit.health.spec import HealthSpec, SpecError
from bagkit.selection.conditions import TopicCondition
from bagkit.selection.errors import SelectionError


@dataclass
class Assertion:
    """One line of the contract on one bag: whether it held, and where it broke.

    Attributes:
        topic, what: the topic and what is asserted (``present``, ``type ...``, or the
            condition that must never hold).
        spans: where it broke, rows ``(start_ns, end_ns, count)`` (log time).
        reason: why, for a topic missing or of another type.
    """

    topic: str
    what: str
    passed: bool
    spans: np.ndarray = field(default_factory=NO_SPANS.copy)
    reason: str = ""

    def commands(self, bag: str, bag_start_ns: int) -> list[str]:
        """Commands that replay and cut the first place it broke."""
        if not len(self.spans):
            return []
        start_ns = int(self.spans[0][0])
        offset = max(start_ns - bag_start_ns - 5_000_000_000, 0) / 1e9
        around = shlex.quote(f"{self.topic}: {self.what}")
        return [
            f"bagkit play {shlex.quote(bag)} --start-offset {offset:.3f}",
            f"bagkit filter {shlex.quote(bag)} -o cut --around {around} --before 5 --after 5",
        ]


@dataclass
class HealthReport:
    """The contract on one bag."""

    bag: str
    start_ns: int
    assertions: list[Assertion]
    problems: list[str] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        """Whether every assertion held."""
        return all(a.passed for a in self.assertions)

    @property
    def exit_code(self) -> int:
        """0 healthy, 1 a contract broken."""
        return 0 if self.passed else 1

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: per assertion its verdict, where it broke (bag seconds) and commands."""
        return {
            "bag": self.bag,
            "passed": self.passed,
            "problems": self.problems,
            "assertions": [
                {
                    "topic": a.topic,
                    "assertion": a.what,
                    "passed": a.passed,
                    "reason": a.reason,
                    "episodes": [
                        {
                            "start_s": (s - self.start_ns) / 1e9,
                            "end_s": (e - self.start_ns) / 1e9,
                            "start_ns": s,
                            "end_ns": e,
                            "count": n,
                        }
                        for s, e, n in a.spans.tolist()
                    ],
                    "commands": a.commands(self.bag, self.start_ns),
                }
                for a in self.assertions
            ],
        }


def check_bag(bag: str | Path, spec: HealthSpec) -> HealthReport:
    """Evaluate ``spec`` on ``bag``.

    Raises:
        BagError: the bag cannot be read; SpecError: a condition names a field the topic's
            type lacks (or compares text with a number).
    """
    found: list[Assertion] = []
    with BagReader(bag, allow_empty=True) as reader:
        counts = reader.topic_counts
        for topic in spec.forbidden:
            present = counts.get(topic, 0) > 0
            reason = f"{counts.get(topic, 0)} messages" if present else ""
            found.append(Assertion(topic, "forbidden", not present, reason=reason))
        for contract in spec.topics:
            topic = contract.topic
            if not counts.get(topic, 0):
                reason = "not in the bag" if topic not in reader.topics else "no message"
                found.append(Assertion(topic, "present", False, reason=reason))
                continue
            found.append(Assertion(topic, "present", True))
            if contract.type is not None:
                actual = canonical_type_name(reader.topics[topic].type)
                same = actual == canonical_type_name(contract.type)
                found.append(
                    Assertion(topic, f"type {contract.type}", same, reason="" if same else actual)
                )
            for text, condition in contract.never:
                try:
                    episodes = find_episodes(reader, TopicCondition(topic, condition))
                except SelectionError as exc:
                    raise SpecError(f"{spec.source}: {topic}: {exc}") from None
                found.append(Assertion(topic, text, not len(episodes.spans), episodes.spans))
        return HealthReport(str(bag), reader.start_ns, found, list(reader.problems))
