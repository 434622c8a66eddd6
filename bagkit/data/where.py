"""``filter --where``: which messages of each topic a condition keeps.

A per-message condition is matched on each payload
(:class:`~bagkit.decode.matcher.PayloadMatcher`), a condition over time keeps the messages
inside its intervals on their topic (:class:`~bagkit.data.streams.IntervalFilter`).
"""

from __future__ import annotations

from collections.abc import Callable, Collection

from bagkit.bag import BagReader
from bagkit.bag.latched import is_state_topic
from bagkit.data.errors import UndecodableTopicError, UnknownFieldError
from bagkit.data.streams import IntervalFilter, temporal_intervals
from bagkit.decode import DecodeError, MessageTypes
from bagkit.decode.matcher import PayloadMatcher
from bagkit.selection.conditions import Condition
from bagkit.selection.windows import Window


def where_filters(
    reader: BagReader,
    condition: Condition,
    passes: Callable[[str], bool],
    *,
    state_topics: Collection[str] = (),
) -> dict[str, PayloadMatcher | IntervalFilter]:
    """A filter for each topic of an open bag that ``passes`` and whose type has every field
    ``condition`` reads (``filter --where``: the other topics are kept whole). A condition
    over time keeps the messages inside its intervals on their topic
    (:class:`bagkit.data.streams.IntervalFilter`); ``state_topics`` hold until their next
    message, as transient-local ones do.

    Raises:
        UnknownFieldError: no such topic (the message names the fields of the first one).
    """
    types = MessageTypes.for_bag(reader)
    matchers: dict[str, PayloadMatcher | IntervalFilter] = {}
    first_error: UnknownFieldError | None = None
    for name in sorted(reader.topics):
        if not passes(name) or reader.topics[name].serialization_format != "cdr":
            continue
        try:
            if condition.temporal:
                state = is_state_topic(reader, name, state_topics)
                spans = temporal_intervals(reader, name, condition, Window(), state)[0]
                matchers[name] = IntervalFilter(spans)
            else:
                matchers[name] = PayloadMatcher(types, name, reader.topics[name].type, condition)
        except (DecodeError, UndecodableTopicError):  # cannot be decoded: the topic is whole
            continue
        except UnknownFieldError as exc:
            first_error = first_error or exc
    if not matchers:
        if first_error is not None:
            raise UnknownFieldError(
                f"no selected topic has the fields of the condition: {first_error}"
            )
        raise UnknownFieldError("no selected topic can be decoded to check the condition")
    return matchers
