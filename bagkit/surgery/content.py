"""``--where`` on ``filter`` and ``convert``: a selection's condition compiled against its inputs.

Each selected topic whose type has the condition's fields gets a filter
(:func:`bagkit.data.where.where_filters`: per message, or the intervals of a condition over
time); the other topics are kept whole. Done once per selection, before any bag is written.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from bagkit.bag import BagReader
from bagkit.surgery.select import PayloadFilter, Selection


def with_content(bags: Sequence[Path], selection: Selection) -> Selection:
    """``selection`` with its condition compiled into per-topic filters (the first input's
    filter where several bags share a topic); as given when it has no condition or has them.

    Raises:
        UnknownFieldError: no selected topic has the condition's fields; UndecodableTopicError.
    """
    if selection.where is None or selection.content:
        return selection
    from bagkit.data.where import where_filters  # numpy, rosbags: only when asked

    content: dict[str, PayloadFilter] = {}
    for bag in bags:
        with BagReader(bag) as reader:
            found = where_filters(
                reader,
                selection.where,
                selection.topic_passes,
                state_topics=selection.state_topics,
            )
        for topic, matcher in found.items():
            content.setdefault(topic, matcher)
    return replace(selection, content=content)
