"""Definitions a bag does not store but a distribution's type store gave (Foxy to Humble
``.db3``, :attr:`~bagkit.bag.BagReader.assumed_types`): checked before a rewrite stores them."""

from __future__ import annotations

from collections.abc import Collection

from bagkit.bag import BagReader
from bagkit.decode import MessageTypes
from bagkit.decode.errors import DecodeError
from bagkit.surgery.errors import SurgeryError


def check_assumed_definitions(reader: BagReader, topics: Collection[str] | None = None) -> None:
    """Decode the first message of each topic (of ``topics``, when given) whose type's
    definition is assumed with that definition: an output stores it, so payloads that do not
    follow it (a Humble ``Range`` read as Jazzy's) would make a bag no reader decodes.

    Raises:
        SurgeryError: a first message does not decode; the message says ``--distro``.
    """
    assumed = reader.assumed_types
    if not assumed:
        return
    types = MessageTypes.for_bag(reader)
    for name, info in sorted(reader.topics.items()):
        if info.type not in assumed or (topics is not None and name not in topics):
            continue
        first = next(reader.messages([name]), None)
        if first is None:
            continue
        try:
            types.for_topic(name).deserialize(first.data, info.type)
        except DecodeError as exc:
            raise SurgeryError(
                f"{name}: {reader.path} stores no definition of {info.type} and its messages "
                f"do not decode with the one assumed ({exc}); name the ROS 2 distribution "
                "that recorded it with --distro"
            ) from exc
