"""Errors of the selection vocabulary: topics, times, windows, field paths and conditions."""

from __future__ import annotations

from bagkit.errors import OptionError


class SelectionError(OptionError):
    """A selection that cannot be understood: a bad regex, time, window or condition."""


class UnknownTopicError(SelectionError):
    """A topic the bag (or bags) does not have; the message names the closest ones it has."""


class UnknownFieldError(SelectionError):
    """A field (path or glob) the topic's type does not have; the message names its fields."""


class EmptyWindowWarning(UserWarning):
    """A time window that holds none of a bag's messages: the result is empty, not an error."""
