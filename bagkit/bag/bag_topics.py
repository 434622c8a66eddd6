"""The topics of a bag being written: their Schema and Channel records and message counts."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

from bagkit.bag.definitions import (
    canonical_type_name,
    definition_encoding,
    message_definition,
    type_description_hash,
)
from bagkit.bag.errors import BagError, UnknownMessageTypeError
from bagkit.bag.mcapio.records import Channel, Schema
from bagkit.bag.messages import TopicInfo
from bagkit.selection.actions import is_action_type
from bagkit.selection.services import is_service_event_type


class BagTopics:
    """Topics by name, one Schema per type and one Channel per topic (ids from 1), counts."""

    def __init__(self) -> None:
        self.topics: dict[str, TopicInfo] = {}
        self.schemas: dict[str, Schema] = {}
        self.channels: dict[str, Channel] = {}
        self.channel_topics: dict[int, str] = {}
        self.counts: dict[int, int] = {}

    def add(self, topic: TopicInfo, definition: str | None) -> list[Schema | Channel]:
        """Add ``topic``; return the records it needs written (none when already added).

        Raises:
            UnknownMessageTypeError: ``definition`` is None and the type is not installed.
            BagError: the topic was already added with another type.
        """
        known = self.topics.get(topic.name)
        if known is not None:
            if known.type != topic.type:
                raise BagError(
                    f"topic {topic.name} already added with type {known.type}, not {topic.type}"
                )
            return []
        records: list[Schema | Channel] = []
        topic = _with_type_hash(topic, definition)
        schema = self.schemas.get(topic.type)
        if schema is None:
            schema = _schema(len(self.schemas) + 1, topic.type, definition)
            self.schemas[topic.type] = schema
            records.append(schema)
        elif definition is not None and schema.data != definition.encode("utf-8"):
            # Another text of the type (a topic of another version): a schema of its own, keyed
            # by type and text (the first text of a type is keyed by its name).
            key = f"{topic.type}\n{definition}"
            if key not in self.schemas:
                self.schemas[key] = _schema(len(self.schemas) + 1, topic.type, definition)
                records.append(self.schemas[key])
            schema = self.schemas[key]
        metadata = {"offered_qos_profiles": topic.offered_qos_profiles}
        if topic.type_description_hash:
            metadata["topic_type_hash"] = topic.type_description_hash
        channel = Channel(
            id=len(self.channels) + 1,
            schema_id=schema.id,
            topic=topic.name,
            message_encoding=topic.serialization_format,
            metadata=metadata,
        )
        self.channels[topic.name] = channel
        self.channel_topics[channel.id] = topic.name
        self.topics[topic.name] = topic
        self.counts[channel.id] = 0
        records.append(channel)
        return records

    def by_topic(self, counts: dict[int, int]) -> dict[str, int]:
        """``counts`` per channel id, per topic name."""
        return {self.channel_topics[c]: n for c, n in counts.items()}

    def with_counts(self, counts: Mapping[int, int] | None = None) -> list[tuple[TopicInfo, int]]:
        """Each topic with its message count (for metadata.yaml), or its count in ``counts``
        (per channel id: one file's)."""
        counts = self.counts if counts is None else counts
        return [
            (topic, counts.get(self.channels[name].id, 0)) for name, topic in self.topics.items()
        ]


def _with_type_hash(topic: TopicInfo, definition: str | None) -> TopicInfo:
    """``topic`` with its type hash filled from the installed type description when missing
    and the bag stores the installed definition (``definition`` None or the same text).

    A definition of another version of the type (a bag recorded before a message changed)
    gets no hash: the installed type's would claim the bag holds today's type.

    A service-event topic gets none: rosbags checks each channel's hash against its own and
    cannot compute a service event's (it names the type ``pkg/srv/msg/Name_Event``), so with
    it rosbags would refuse the whole bag (docs/record.md, "Services"). Nor does a type derived
    from an action (``pkg/action/Name_FeedbackMessage``), for the same reason.
    """
    if is_service_event_type(topic.type) or is_action_type(topic.type):
        return dataclasses.replace(topic, type_description_hash="")
    if topic.type_description_hash:
        return topic
    canonical = canonical_type_name(topic.type)
    try:
        if definition is not None and definition != message_definition(canonical):
            return topic
        hash_string = type_description_hash(canonical)
    except UnknownMessageTypeError:
        return topic
    return TopicInfo(
        topic.name,
        topic.type,
        topic.serialization_format,
        topic.offered_qos_profiles,
        hash_string,
    )


def _schema(schema_id: int, type_name: str, definition: str | None) -> Schema:
    """The Schema record of a type; ``definition`` None reads it from the installed files."""
    text = message_definition(canonical_type_name(type_name)) if definition is None else definition
    return Schema(
        id=schema_id, name=type_name, encoding=definition_encoding(text), data=text.encode("utf-8")
    )
