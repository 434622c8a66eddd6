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
from collections.abc import Callable, Iterable, Sequence
from typing import Protocol, TypeVar

from bagkit.selection.errors import UnknownFieldError
from bagkit.selection.topics import did_you_mean


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


class HasPath(Protocol):
    """A leaf field: anything with a ``path`` (``bagkit.decode.LeafField``)."""

    @property
    def path(self) -> str: ...


Leaf = TypeVar("Leaf", bound=HasPath)


def select_fields(
    leaves: Sequence[Leaf], patterns: Sequence[str] | None, *, topic: str, must_match: bool = True
) -> list[Leaf]:
    """The leaves matching any of ``patterns`` (all when None), in definition order.

    A pattern is a path or glob (``linear_acceleration.*``, ``orientation_covariance[0]``,
    ``ranges[]``); a path also selects everything under it (``header`` selects
    ``header.stamp.sec``, ``header.stamp.nanosec``, ``header.frame_id``).

    Raises:
        UnknownFieldError: with ``must_match``, a pattern matches no leaf; the message names the
            topic's fields, whole, and the closest to the pattern.
    """
    if not patterns:
        return list(leaves)
    unmatched = [p for p in patterns if not any(path_matches(leaf.path, p) for leaf in leaves)]
    if unmatched and must_match:
        raise UnknownFieldError(unknown_field_message(topic, unmatched, [x.path for x in leaves]))
    return [leaf for leaf in leaves if any(path_matches(leaf.path, p) for p in patterns)]


def unknown_field_message(topic: str, unmatched: Sequence[str], paths: Sequence[str]) -> str:
    """``/imu/data has no field x (did you mean y? it has a.{x,y,z}, b[0..8])``."""
    guess = did_you_mean(unmatched[0], paths)
    listing = describe_paths(paths) if paths else "none"
    return f"{topic} has no field {', '.join(unmatched)} ({guess}it has {listing})"


def describe_paths(paths: Sequence[str]) -> str:
    """Leaf paths, whole but short: ``orientation.{x,y,z,w}, orientation_covariance[0..8]``."""
    runs: list[tuple[str, list[str]]] = []  # (parent, last components) in definition order
    for path in _fold_indexes(paths):
        parent, dot, last = path.rpartition(".")
        if dot and runs and runs[-1][0] == parent and "[" not in last:
            runs[-1][1].append(last)
        else:
            runs.append((parent if dot and "[" not in last else "", [last if dot else path]))
    return ", ".join(
        f"{parent}.{{{','.join(names)}}}"
        if len(names) > 1
        else f"{parent}.{names[0]}"
        if parent
        else names[0]
        for parent, names in runs
    )


def _fold_indexes(paths: Sequence[str]) -> list[str]:
    """``a[0]``, ``a[1]``, ``a[2]`` -> ``a[0..2]``: fixed arrays printed once."""
    folded: list[str] = []
    index = re.compile(r"^(.*)\[(\d+)\]$")
    run: tuple[str, int, int] | None = None  # (stem, first, last)
    for path in [*paths, ""]:
        match = index.match(path)
        if run and match and match[1] == run[0] and int(match[2]) == run[2] + 1:
            run = (run[0], run[1], run[2] + 1)
            continue
        if run:
            folded.append(
                f"{run[0]}[{run[1]}..{run[2]}]" if run[2] > run[1] else f"{run[0]}[{run[1]}]"
            )
            run = None
        if match:
            run = (match[1], int(match[2]), int(match[2]))
        elif path:
            folded.append(path)
    return folded
