"""The records the bag layer hands out: a topic's description and one stored message."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class TopicInfo:
    """A topic of a bag, as rosbag2 describes it in ``metadata.yaml`` and MCAP channels."""

    name: str
    type: str
    serialization_format: str = "cdr"
    offered_qos_profiles: str = ""
    type_description_hash: str = ""


@dataclass(frozen=True, slots=True)
class BagMessage:
    """One serialized message exactly as stored, with its times in nanoseconds."""

    topic: str
    data: bytes
    log_time: int
    publish_time: int
    sequence: int
