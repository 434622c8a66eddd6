"""``--where`` on ``filter`` and ``convert``: a selection's condition compiled against its inputs.

Each selected topic whose type has the condition's fields (or only the topic it names:
``'TOPIC: CONDITION'``) gets a filter (:func:`bagkit.data.where.where_filters`: per message,
or the intervals of a condition over time); the other topics are kept whole. Done once per
selection, before any bag is written.
"""

from __future__ import annotations

from collections.abc import Sequence
from contextlib import ExitStack
from dataclasses import replace
from pathlib import Path

from bagkit.bag import BagReader
from bagkit.selection.topics import require_topics
from bagkit.surgery.options import stored_names
from bagkit.surgery.select import PayloadFilter, Selection


def with_content(bags: Sequence[Path], selection: Selection) -> Selection:
    """``selection`` with its named topics as the inputs store them (a service's name is its
    event topic) and its condition compiled into per-topic filters (the first input's filter
    where several bags share a topic); as given when it has no condition or has them.

    Raises:
        UnknownTopicError: a named topic is in no input; UnknownFieldError: no selected topic
            has the condition's fields; UndecodableTopicError.
    """
    condition = selection.where
    if condition is None or selection.content:
        return selection
    from bagkit.data.where import where_filters  # numpy, rosbags: only when asked

    with ExitStack() as stack:
        readers = [stack.enter_context(BagReader(bag)) for bag in bags]
        names = {name for r in readers for name in r.topics}
        selection = stored_names(selection, names)
        topics = selection.topics
        named = selection.where_topic
        only = None if named is None else set(require_topics([named], names))

        def passes(name: str) -> bool:
            return (only is None or name in only) and topics.matches(name)

        content: dict[str, PayloadFilter] = {}
        for reader in readers:
            found = where_filters(reader, condition, passes, state_topics=selection.state_topics)
            for topic, matcher in found.items():
                content.setdefault(topic, matcher)
    return replace(selection, content=content)
