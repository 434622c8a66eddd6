"""What a health contract found on bags: one :class:`Assertion` per line of the contract, a
:class:`HealthReport` per bag and the :class:`CheckResult` of them all, with their exit codes,
JSON and the commands and links that lead to where each broke."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bagkit.data.episodes import NO_SPANS
from bagkit.health.links import filter_command, foxglove_link, play_command
from bagkit.words import counted

EXIT_HEALTHY, EXIT_BROKEN, EXIT_BAD_INPUT = 0, 1, 2


@dataclass
class Assertion:
    """One line of the contract on one bag: whether it held, and where it broke.

    Attributes:
        topic, what: the topic and what is asserted (``present``, ``type ...``,
            ``forbidden``, or the condition that must never hold).
        spans: where it broke, rows ``(start_ns, end_ns, count)`` (log time).
        reason: why, for a topic missing, present though forbidden, or of another type.
    """

    topic: str
    what: str
    passed: bool
    spans: np.ndarray = field(default_factory=NO_SPANS.copy)
    reason: str = ""

    @property
    def is_condition(self) -> bool:
        """Whether ``what`` is a condition over the topic's messages (it has spans)."""
        return self.what not in ("present", "forbidden") and not self.what.startswith("type ")

    def summary(self, bag_start_ns: int) -> str:
        """One line: what broke, why, how often and first where (seconds from the start)."""
        where = self.where(bag_start_ns)
        return f"{self.headline}: {where}" if where else self.headline

    @property
    def headline(self) -> str:
        """What is asserted, and why it broke where that is not a place in time."""
        text = f"{self.topic}: {self.what}"
        return f"{text} ({self.reason})" if self.reason else text

    def where(self, bag_start_ns: int) -> str:
        """How often it broke and first where (seconds from the start); "" without spans."""
        if not len(self.spans):
            return ""
        start, end, _ = self.spans[0].tolist()
        return (
            f"{counted(len(self.spans), 'time')}, first at {(start - bag_start_ns) / 1e9:.3f}"
            f"-{(end - bag_start_ns) / 1e9:.3f} s"
        )

    def commands(self, bag: str, bag_start_ns: int) -> list[str]:
        """Commands that replay the first place it broke and cut every one."""
        if not len(self.spans):
            return []
        return [
            play_command(bag, int(self.spans[0][0]), bag_start_ns),
            filter_command(bag, self.topic, self.what),
        ]


@dataclass
class HealthReport:
    """The contract on one bag (``error``: why it could not be read; then no assertion)."""

    bag: str
    start_ns: int
    assertions: list[Assertion]
    problems: list[str] = field(default_factory=list)
    error: str | None = None
    bags_url: str | None = None
    """Where bags are served (:mod:`bagkit.health.links`): each failure gets a Foxglove link."""
    files: list[tuple[int, str]] = field(default_factory=list)
    """The bag's MCAP files (first log time, name) in time order: a link opens the one that
    holds the break."""

    @property
    def passed(self) -> bool:
        """Whether the bag was read and every assertion held."""
        return self.error is None and all(a.passed for a in self.assertions)

    @property
    def broken(self) -> list[Assertion]:
        """The assertions that did not hold."""
        return [a for a in self.assertions if not a.passed]

    @property
    def exit_code(self) -> int:
        """0 healthy, 1 a contract broken, 2 the bag could not be read."""
        if self.error is not None:
            return EXIT_BAD_INPUT
        return EXIT_HEALTHY if self.passed else EXIT_BROKEN

    def link(self, assertion: Assertion) -> str | None:
        """Foxglove at the first place ``assertion`` broke, where bags are served."""
        if self.bags_url is None or not len(assertion.spans):
            return None
        return foxglove_link(self.bags_url, self.bag, int(assertion.spans[0][0]), self.files)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: per assertion its verdict, where it broke (bag seconds) and commands."""
        return {
            "bag": self.bag,
            "passed": self.passed,
            "error": self.error,
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
                    "foxglove": self.link(a),
                }
                for a in self.assertions
            ],
        }


@dataclass
class CheckResult:
    """The contract on every bag, in the order given."""

    reports: list[HealthReport]

    @property
    def passed(self) -> bool:
        """Whether every bag was read and kept the contract."""
        return all(report.passed for report in self.reports)

    @property
    def exit_code(self) -> int:
        """0 every bag healthy, 1 a contract broken, 2 a bag could not be read."""
        return max((report.exit_code for report in self.reports), default=EXIT_HEALTHY)

    def to_list(self) -> list[dict[str, Any]]:
        """One :meth:`HealthReport.to_dict` per bag."""
        return [report.to_dict() for report in self.reports]
