"""Field paths and the globs that select them: one language for stats, compare and export.

Leaf paths (see :mod:`bagkit.decode.flatten`): nested fields ``linear_acceleration.x``, fixed
arrays one leaf per index ``orientation_covariance[0]``, sequences pooled ``ranges[]`` and
``status[].level``.

A glob selects the paths it matches whole, with two wildcards: ``*`` (any run of characters,
dots and brackets included) and ``?`` (one character). Everything else is literal, brackets
too, so that ``covariance[0]`` and ``ranges[]`` are written as printed. A glob that names a
message, an array or a sequence selects every leaf below it: ``header`` selects
``header.stamp.sec`` ... ``header.frame_id``, ``orientation_covariance`` its nine elements,
``status`` (or ``status[]``) ``status[].level`` ...

``TOPIC_GLOB:FIELD_GLOB`` restricts a field glob to the topics matching ``TOPIC_GLOB`` (the same
wildcards, matched against the whole topic name); a glob without a colon applies to every topic.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Callable, Iterable


def _translate(glob: str) -> str:
    return "".join(".*" if c == "*" else "." if c == "?" else re.escape(c) for c in glob)


@functools.lru_cache(maxsize=1024)
def _name_regex(glob: str) -> re.Pattern[str]:
    return re.compile(_translate(glob), re.DOTALL)


@functools.lru_cache(maxsize=1024)
def _field_regex(globs: tuple[str, ...]) -> re.Pattern[str]:
    # A match may stop where a nested field or an index begins: the glob named a subtree.
    alternatives = "|".join(_translate(glob) for glob in globs)
    return re.compile(f"(?:{alternatives})(?:[.\\[].*)?", re.DOTALL)


def name_matches(name: str, glob: str) -> bool:
    """Whether the whole of ``name`` (a topic) matches ``glob`` (``*``, ``?``, the rest literal)."""
    return _name_regex(glob).fullmatch(name) is not None


def path_matches(path: str, glob: str) -> bool:
    """Whether ``glob`` selects the leaf ``path`` (the path itself or a subtree holding it)."""
    return _field_regex((glob,)).fullmatch(path) is not None


def split_pattern(pattern: str) -> tuple[str, str]:
    """``TOPIC_GLOB:FIELD_GLOB`` -> (topic glob, field glob); a bare field glob -> ("*", glob).

    An empty side means every topic (or every field).
    """
    if ":" in pattern:
        topic, _, path = pattern.partition(":")
        return topic or "*", path or "*"
    return "*", pattern


class FieldSelection:
    """Field patterns (``[TOPIC_GLOB:]FIELD_GLOB``) and what they select; all when empty."""

    def __init__(self, patterns: Iterable[str] | None = None) -> None:
        self.patterns: tuple[str, ...] = tuple(patterns or ())
        self._split = [split_pattern(p) for p in self.patterns]

    def __bool__(self) -> bool:
        return bool(self.patterns)

    def for_topic(self, topic: str) -> Callable[[str], bool]:
        """A predicate on the leaf paths of ``topic``: whether a pattern selects them."""
        if not self.patterns:
            return lambda _path: True
        globs = tuple(field for topic_glob, field in self._split if name_matches(topic, topic_glob))
        if not globs:
            return lambda _path: False
        regex = _field_regex(globs)
        return lambda path: regex.fullmatch(path) is not None

    def selects(self, topic: str, path: str) -> bool:
        """Whether a pattern selects ``path`` on ``topic`` (False when there is no pattern)."""
        return any(
            name_matches(topic, topic_glob) and path_matches(path, field)
            for topic_glob, field in self._split
        )
