"""What the storage files of one bag hold together: topics (what the storage lacks filled in
from ``metadata.yaml``), counts, definitions and the time span, for :class:`BagReader`."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from bagkit.bag.messages import TopicInfo
from bagkit.bag.metadata import BagMetadata
from bagkit.bag.storage import StorageFile


@dataclass(slots=True)
class BagContents:
    """The storage files' topics, counts, definitions and span, merged in file order.

    Attributes:
        storage: the files' storage identifiers, comma-separated (``mcap``, ``sqlite3`` ...).
        topics: by name, the first file's, completed from ``metadata.yaml``; a topic listed
            there alone is one without messages.
        topic_counts: messages per topic over all files.
        definitions: ``ros2msg`` text by type name, the first file's that stores one.
        topic_definitions: per topic, a file's own text where it differs from
            ``definitions``' (a type changed between two split files).
        start_ns, end_ns: the span of the files that hold messages (0 without any).
    """

    storage: str = ""
    topics: dict[str, TopicInfo] = field(default_factory=dict)
    topic_counts: dict[str, int] = field(default_factory=dict)
    definitions: dict[str, str] = field(default_factory=dict)
    topic_definitions: dict[str, str] = field(default_factory=dict)
    start_ns: int = 0
    end_ns: int = 0

    @classmethod
    def of(cls, files: Sequence[StorageFile], metadata: BagMetadata | None) -> BagContents:
        """The contents of the open storage ``files``, with ``metadata.yaml``'s if any."""
        found = cls(",".join(dict.fromkeys(s.storage_identifier for s in files)))
        recorded = {t.name: t for t, _ in metadata.topics} if metadata else {}
        for storage in files:
            for name, topic in storage.topics.items():
                if name not in found.topics:
                    found.topics[name] = _complete(topic, recorded.get(name))
                found.topic_counts[name] = (
                    found.topic_counts.get(name, 0) + storage.topic_counts[name]
                )
            for type_name, text in storage.definitions.items():
                found.definitions.setdefault(type_name, text)
            for name, topic in storage.topics.items():
                own = storage.topic_definitions.get(name, storage.definitions.get(topic.type))
                if own is not None and found.definitions.get(topic.type) != own:
                    found.topic_definitions.setdefault(name, own)
        for name, topic in recorded.items():
            if name not in found.topics:
                found.topics[name] = topic
                found.topic_counts[name] = 0
        with_messages = [s for s in files if any(s.topic_counts.values())]
        found.start_ns = min((s.start_ns for s in with_messages), default=0)
        found.end_ns = max((s.end_ns for s in with_messages), default=0)
        return found


def _complete(topic: TopicInfo, recorded: TopicInfo | None) -> TopicInfo:
    """Fill the QoS and type hash that the storage lacks from ``metadata.yaml``."""
    if recorded is None:
        return topic
    return TopicInfo(
        name=topic.name,
        type=topic.type or recorded.type,
        serialization_format=topic.serialization_format or recorded.serialization_format,
        offered_qos_profiles=topic.offered_qos_profiles or recorded.offered_qos_profiles,
        type_description_hash=topic.type_description_hash or recorded.type_description_hash,
    )
