"""Messages of a topic as plain data (for ``bagkit echo``), streamed in log-time order.

Each message becomes ``{"topic", "log_time", "publish_time", "data"}`` (times in ns), like a
line of ``mcap cat --json``; ``data`` is the message as nested dicts and lists, the shape
``ros2 topic echo`` prints, or, when fields are selected, ``{dotted path: value}``.
"""

from __future__ import annotations

import heapq
import json
import warnings
from collections.abc import Callable, Iterator, Sequence
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from bagkit.bag import BagReader
from bagkit.data.errors import (
    DataLossWarning,
    UndecodableTopicError,
    could_have_lost,
    nothing_read,
)
from bagkit.decode import DecodeError, MessageTypes, leaf_fields
from bagkit.decode.msgdef import EMPTY_STRUCT_MEMBER, Nodetype, TypeDefinitions, member_name
from bagkit.selection.actions import action_part_topics
from bagkit.selection.errors import EmptyWindowWarning
from bagkit.selection.fields import select_fields
from bagkit.selection.query import Query
from bagkit.selection.topics import absolute_topic_name, require_topics
from bagkit.selection.windows import outside_warning

if TYPE_CHECKING:
    from bagkit.decode.matcher import PayloadMatcher

Plain = dict[str, Any]


def echo(
    bag: str | Path,
    query: Query,
    *,
    count: int | None = None,
    limit: int | None = None,
    on_failure: Callable[[str], None] | None = None,
) -> Iterator[Plain]:
    """Yield the messages of the topic ``query`` names one at a time, decoded as read.

    Args:
        query: one topic; its fields (paths or globs: the data is then flat
            ``{path: value}`` of those leaves), its times, its condition (only messages
            satisfying it, e.g. ``status[*].level >= 2``; with terms over time, ``gap > 1s``,
            the messages inside the intervals where it holds).
        count: stop after this many messages.
        limit: sequences longer than this are cut to their first ``limit`` elements followed
            by ``"... (N more)"`` (None: whole).
        on_failure: called with a message that does not decode (skipped); None raises. With
            a condition, messages it cannot decode are not matched and counted in one call at
            the end.

    What could not be read (a damaged chunk) is a :class:`DataLossWarning` at the end; when
    nothing else was read, a ``DataError``.

    Raises:
        BagError, UnknownTopicError, UnknownFieldError, UndecodableTopicError, DecodeError,
        DataError (no message read, some lost);
        SelectionError for a condition that does not parse or compares text with a number.
    """
    condition, fields = query.where, query.fields
    with BagReader(bag, allow_empty=True) as reader:
        (topic,) = require_topics(query.topics, reader.topics)
        info = reader.topics[topic]
        types = MessageTypes.for_bag(reader).for_topic(topic)
        try:
            if info.serialization_format != "cdr":
                raise DecodeError(f"serialization format {info.serialization_format!r} is not CDR")
            canonical = types.resolve(info.type)
        except DecodeError as exc:
            raise UndecodableTopicError(f"{topic} cannot be decoded: {exc}") from None
        convert = _converter(types, info.type, canonical, fields, topic, limit)
        window = query.span.resolve(reader.start_ns, reader.end_ns)
        matcher: PayloadMatcher | None = None
        inside: Callable[[int], bool] | None = None  # a condition over time: inside its intervals
        if condition is not None and condition.temporal:
            # The columns' scan (pyarrow) only for a condition over time: echo starts light.
            from bagkit.bag.latched import is_state_topic
            from bagkit.data.streams import temporal_intervals
            from bagkit.selection.intervals import holds_at

            state = is_state_topic(reader, topic)
            spans = temporal_intervals(reader, topic, condition, window, state)[0]
            inside = partial(holds_at, spans)
        elif condition is not None:
            # The condition's bulk decoder only with a condition: echo starts light.
            from bagkit.decode.matcher import PayloadMatcher

            matcher = PayloadMatcher(types, topic, info.type, condition, bulk=False)
        if reader.message_count:
            outside = outside_warning(str(bag), window, reader.start_ns, reader.end_ns)
            if outside is not None:
                warnings.warn(outside, EmptyWindowWarning, stacklevel=2)
        done = 0
        for message in reader.messages([topic], window.start_ns, window.end_ns):
            if count is not None and done >= count:
                return
            if matcher is not None and not matcher.matches(message.data):
                continue
            if inside is not None and not inside(message.log_time):
                continue
            try:
                data = convert(message.data)
            except DecodeError as exc:
                if on_failure is None:
                    raise
                on_failure(f"{topic} at {message.log_time}: {exc}")
                continue
            done += 1
            yield {
                "topic": topic,
                "log_time": message.log_time,
                "publish_time": message.publish_time,
                "data": data,
            }
        if matcher is not None and matcher.problem is not None:
            if on_failure is None:
                raise DecodeError(matcher.problem)
            on_failure(matcher.problem)
        if not done and could_have_lost(reader, topic):  # nothing to show, chunks were lost
            raise nothing_read([topic], reader.problems)
        for problem in reader.problems:
            warnings.warn(f"{bag}: {problem}", DataLossWarning, stacklevel=2)


def action_topics(reader: BagReader, name: str) -> list[str]:
    """The recorded topics of action ``name`` of an open bag when ``name`` is an action and not
    one of its topics (``echo``'s choice), else ``[]``."""
    if absolute_topic_name(name) in {absolute_topic_name(t) for t in reader.topics}:
        return []
    return action_part_topics(name, ((t, i.type) for t, i in reader.topics.items()))


def names_service(reader: BagReader, name: str) -> bool:
    """Whether ``name`` is a service of an open bag and not one of its topics (``echo``'s
    choice)."""
    if absolute_topic_name(name) in {absolute_topic_name(t) for t in reader.topics}:
        return False
    # The service modules for a name that is no topic only: echo of a topic starts without.
    from bagkit.data.service_summaries import find_service

    return find_service(reader, name) is not None


def echo_action(
    bag: str | Path,
    query: Query,
    *,
    limit: int | None = None,
    on_failure: Callable[[str], None] | None = None,
) -> Iterator[Plain]:
    """Yield the messages of every recorded topic of the action ``query`` names (feedback,
    status and its services' events) in its window, each decoded with its own topic's
    definition, in log-time order.

    Raises:
        UnknownTopicError: the name is no action of ``bag``; as :func:`echo` otherwise.
    """
    (name,) = query.topics
    with BagReader(bag, allow_empty=True) as reader:
        topics = action_topics(reader, name)
        if not topics:
            require_topics([name], reader.topics)  # raises: names the closest topics
    streams = [echo(bag, query.with_topics(t), limit=limit, on_failure=on_failure) for t in topics]
    yield from heapq.merge(*streams, key=lambda record: record["log_time"])


def _converter(  # noqa: PLR0917 (private, called once)
    types: MessageTypes,
    type_name: str,
    canonical: str,
    fields: Sequence[str] | None,
    topic: str,
    limit: int | None,
) -> Callable[[bytes], Any]:
    if fields:
        leaves = select_fields(leaf_fields(types.typestore, canonical), fields, topic=topic)
        paths = [leaf.path for leaf in leaves]
        read = types.value_reader(type_name, paths)
        return lambda data: {p: _plain(v, limit) for p, v in zip(paths, read(data), strict=True)}
    decode = types.decoder(type_name, lists=True)
    store = types.typestore
    return lambda data: _message(decode(data), store, canonical, limit)


def _message(msg: Any, store: TypeDefinitions, typename: str, limit: int | None) -> Plain:
    return {
        name: _field(getattr(msg, member_name(name)), desc, store, limit)
        for name, desc in store.fielddefs[typename][1]
        if name != EMPTY_STRUCT_MEMBER[0]  # CDR's stand-in, not a field of the .msg
    }


def _field(value: Any, desc: Any, store: TypeDefinitions, limit: int | None) -> Any:
    kind, rest = desc
    if kind == Nodetype.BASE:
        return _scalar(value, rest[0])
    if kind == Nodetype.NAME:
        return _message(value, store, rest, limit)
    sub = rest[0]
    if sub[0] != Nodetype.BASE:
        return _plain([_field(v, sub, store, limit) for v in value], limit)
    return _plain(value, limit, base=sub[1][0])


def _scalar(value: Any, base: str | None) -> Any:
    if base == "bool":
        return bool(value)
    if base in ("byte", "char"):
        return int(value) & 0xFF  # an octet, whatever sign the decoder gave it
    return value.item() if hasattr(value, "item") else value  # a numpy number as Python's


def _plain(value: Any, limit: int | None, base: str | None = None) -> Any:
    """Numpy values as Python ones; long sequences cut to ``limit`` elements."""
    if hasattr(value, "tolist"):  # numpy's (fields read straight from the bytes): no import
        value = value.tolist()
    if isinstance(value, list):
        # Octets and booleans need converting; other numbers are Python's after tolist().
        items = [_scalar(v, base) for v in value] if base in ("bool", "byte", "char") else value
        if limit is not None and len(items) > limit:
            return [*items[:limit], f"... ({len(items) - limit} more)"]
        return items
    return _scalar(value, base)


def to_json(record: Plain) -> str:
    """One line of JSON (NaN and infinities as ``NaN``/``Infinity``, as Python and pandas read)."""
    return json.dumps(record, ensure_ascii=False, separators=(",", ":"))


_Dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)


def to_yaml(record: Plain, bag_start_ns: int) -> str:
    """A YAML document for people: a comment with the time, then the record; ends with ``---``."""
    seconds = (record["log_time"] - bag_start_ns) / 1e9
    head = f"# {record['topic']} at {seconds:.9f} s\n"
    body = yaml.dump(record, Dumper=_Dumper, sort_keys=False, allow_unicode=True, width=100)
    return head + body + "---\n"
