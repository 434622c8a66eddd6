"""Which calls of a recorded service a query keeps: its time window and its condition.

``echo BAG /service --start/--end/--where`` applies to calls what the same options apply to a
topic's messages. A call sits at its first event's log time. A condition reads the call as
``echo`` prints it: ``request.FIELD``, ``response.FIELD``, ``latency_s`` and
``sequence_number`` (``--where 'response.success == false or latency_s > 0.1'``). A call
without a part the condition reads (its response not recorded, no latency on either side)
does not match.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from bagkit.bag import BagReader
from bagkit.bag.service_calls import ServiceCall
from bagkit.decode import MessageTypes, leaf_fields
from bagkit.decode.flatten import STRING_TYPES
from bagkit.selection.query import Query
from bagkit.selection.services import service_name
from bagkit.selection.topics import absolute_topic_name

if TYPE_CHECKING:
    from bagkit.selection.conditions import Condition

# The event type's sequences of at most one element, read as the part itself.
_PARTS = ("request", "response")
_NUMBERS = ("latency_s", "sequence_number")


@dataclass(frozen=True, slots=True)
class _CallFields:
    """What a condition on a call reads (the names ``echo`` prints)."""

    request: Any
    response: Any
    latency_s: float | None
    sequence_number: int


def call_filter(
    reader: BagReader, types: MessageTypes, topic: str, query: Query
) -> Callable[[ServiceCall], bool]:
    """Whether ``query`` (its window resolved against the bag, its condition) keeps a call of
    the service whose events are on ``topic``.

    Raises:
        SelectionError: the condition reads more than one call (over time), or compares text
            with a number; UnknownFieldError: it names no field of the calls.
    """
    window = query.span.resolve(reader.start_ns, reader.end_ns)
    condition = query.where
    if condition is not None:
        condition.require_per_message()
        paths, texts = _call_paths(types, reader.topics[topic].type)
        condition.check_fields(service_name(absolute_topic_name(topic)), paths, texts)

    def keep(call: ServiceCall) -> bool:
        if not window.contains(call.log_time_ns):
            return False
        return condition is None or _satisfies(condition, call)

    return keep


def _call_paths(types: MessageTypes, event_type: str) -> tuple[list[str], set[str]]:
    """The leaf paths a condition may name, and those holding text."""
    paths: list[str] = list(_NUMBERS)
    texts: set[str] = set()
    for leaf in leaf_fields(types.typestore, types.resolve(event_type)):
        part, _, rest = leaf.path.partition("[].")
        if part in _PARTS and rest:
            paths.append(f"{part}.{rest}")
            if leaf.base in STRING_TYPES:
                texts.add(f"{part}.{rest}")
    return paths, texts


def _satisfies(condition: Condition, call: ServiceCall) -> bool:
    latency = call.latency_ns
    fields = _CallFields(
        call.request, call.response, None if latency is None else latency / 1e9, call.call[1]
    )
    read = {str(node.path[0]) for node in condition.comparisons() if node.path is not None}
    if any(getattr(fields, name) is None for name in read):
        return False
    return condition.matches(fields)
