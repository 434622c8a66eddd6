"""What a rewrite carries over from its inputs besides their messages: the latched state
before its window, and metadata.yaml's ``custom_data``.

Latched state (``filter``/``merge`` with ``--start``, each ``--around`` window): before the
window's first message, the last message before the window's start of each selected topic
recorded transient-local (plus ``--latched-topics``; none with ``--no-latched``), found from
the inputs' indexes (:mod:`bagkit.bag.latched`). The copies are logged at the window's start
(so the output starts where the window does and a replay publishes them first); their publish
time, sequence number and payload stay as recorded. Over several inputs, the latest message
of each topic wins (equal times: the later input).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from bagkit.bag import BagMessage, BagReader
from bagkit.bag.latched import latched_topics
from bagkit.bag.messages import TopicInfo
from bagkit.surgery.output import MessageOutput
from bagkit.surgery.select import Selection


def latched_messages(
    bags: Sequence[Path], known: dict[str, TopicInfo], selection: Selection
) -> list[BagMessage]:
    """The latched state of ``bags`` at the start of ``selection``'s resolved window, in the
    order it is written (original log time, then topic); none without a start.

    Args:
        bags: the inputs.
        known: every input's topics (``--latched-topics`` names must be among them).
        selection: the resolved selection (its window, topics and latched options).

    Raises:
        UnknownTopicError: a ``--latched-topics`` name is in no input.
    """
    start = selection.window.start_ns
    if start is None:
        return []
    selected = [name for name in known if selection.topic_passes(name)]
    topics = latched_topics(known, selection.latched, selected)
    if not topics:
        return []
    found: dict[str, BagMessage] = {}
    for bag in bags:
        with BagReader(bag, allow_empty=True) as reader:
            for topic, message in reader.last_messages(topics & set(reader.topics), start).items():
                if topic not in found or message.log_time >= found[topic].log_time:
                    found[topic] = message
    return sorted(found.values(), key=lambda m: (m.log_time, m.topic))


def write_latched(out: MessageOutput, messages: list[BagMessage], start_ns: int) -> None:
    """Write ``messages`` at log time ``start_ns`` before anything else of the window."""
    for message in messages:
        out.write_message(out.topic_id(message.topic), message, start_ns)


def merged_custom_data(per_bag: Sequence[tuple[str, Mapping[str, str]]]) -> dict[str, str]:
    """The inputs' ``custom_data`` (metadata.yaml's) for the output, from ``(bag name, data)``
    of each input.

    One input: as it is. Several: a key with one value wherever it appears is kept as it is;
    a key the inputs disagree on is kept per input, as ``BAGNAME/KEY``, so no input's figure
    (the recorder's loss counts) is lost or mixed with another's.
    """
    if len(per_bag) == 1:
        return dict(per_bag[0][1])
    values: dict[str, set[str]] = {}
    for _, data in per_bag:
        for key, value in data.items():
            values.setdefault(key, set()).add(value)
    merged: dict[str, str] = {}
    for name, data in per_bag:
        for key, value in data.items():
            merged[key if len(values[key]) == 1 else f"{name}/{key}"] = value
    return merged
