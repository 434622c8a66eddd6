"""rosbag2's ``metadata.yaml``: write version 9 (Jazzy), read versions 1 to 9."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from bagkit.bag.errors import NotABagError
from bagkit.bag.types import TopicInfo

METADATA_FILENAME = "metadata.yaml"
METADATA_VERSION = 9
ROS_DISTRO = "jazzy"
_ROOT_KEY = "rosbag2_bagfile_information"


@dataclass(frozen=True, slots=True)
class FileInformation:
    """One storage file of a bag, as listed under ``files``."""

    path: str
    starting_time: int
    duration: int
    message_count: int


@dataclass(slots=True)
class BagMetadata:
    """The content of ``metadata.yaml`` (``rosbag2_bagfile_information``)."""

    storage_identifier: str
    relative_file_paths: list[str]
    starting_time: int = 0
    duration: int = 0
    message_count: int = 0
    topics: list[tuple[TopicInfo, int]] = field(default_factory=list)
    files: list[FileInformation] = field(default_factory=list)
    compression_format: str = ""
    compression_mode: str = ""
    custom_data: dict[str, str] = field(default_factory=dict)
    ros_distro: str = ROS_DISTRO
    version: int = METADATA_VERSION

    def to_dict(self) -> dict[str, Any]:
        """Return the fields in the order and shape rosbag2 writes them (inside the root key)."""
        return {
            "version": self.version,
            "storage_identifier": self.storage_identifier,
            "duration": {"nanoseconds": self.duration},
            "starting_time": {"nanoseconds_since_epoch": self.starting_time},
            "message_count": self.message_count,
            "topics_with_message_count": [
                {
                    "topic_metadata": {
                        "name": topic.name,
                        "type": topic.type,
                        "serialization_format": topic.serialization_format,
                        "offered_qos_profiles": topic.offered_qos_profiles,
                        "type_description_hash": topic.type_description_hash,
                    },
                    "message_count": count,
                }
                for topic, count in self.topics
            ],
            "compression_format": self.compression_format,
            "compression_mode": self.compression_mode,
            "relative_file_paths": list(self.relative_file_paths),
            "files": [
                {
                    "path": f.path,
                    "starting_time": {"nanoseconds_since_epoch": f.starting_time},
                    "duration": {"nanoseconds": f.duration},
                    "message_count": f.message_count,
                }
                for f in self.files
            ],
            "custom_data": dict(self.custom_data),
            "ros_distro": self.ros_distro,
        }

    def dump(self, *, root: bool = True) -> str:
        """Serialize as YAML; ``root=False`` omits the root key (the MCAP ``rosbag2`` record)."""
        content: dict[str, Any] = self.to_dict()
        if root:
            content = {_ROOT_KEY: content}
        return yaml.dump(
            content,
            Dumper=yaml.CSafeDumper,
            sort_keys=False,
            default_flow_style=False,
            width=1 << 16,
        )


def write_metadata(bag_dir: Path, metadata: BagMetadata) -> None:
    """Write ``metadata.yaml`` atomically (a crash never leaves half a file)."""
    target = bag_dir / METADATA_FILENAME
    partial = target.with_name(METADATA_FILENAME + ".partial")
    try:
        partial.write_text(metadata.dump(), encoding="utf-8")
        partial.replace(target)
    except OSError:
        partial.unlink(missing_ok=True)  # a full disk must not leave half a file behind
        raise


def _qos_text(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, str):
        return value
    return yaml.safe_dump(value, sort_keys=False, default_flow_style=False)


def _int(node: Any, key: str) -> int:
    if isinstance(node, dict):
        return int(node.get(key) or 0)
    return int(node or 0)


def parse_metadata(text: str, *, source: str = METADATA_FILENAME) -> BagMetadata:
    """Parse ``metadata.yaml`` content of any rosbag2 version (1 to 9).

    Raises:
        NotABagError: not YAML, or not rosbag2 metadata.
    """
    try:
        # libyaml: the pure-Python loader took tens of milliseconds per bag opened.
        document = yaml.load(text, Loader=yaml.CSafeLoader)
    except yaml.YAMLError as exc:
        raise NotABagError(f"{source}: not valid YAML ({exc})") from exc
    if isinstance(document, dict) and _ROOT_KEY in document:
        document = document[_ROOT_KEY]
    if not isinstance(document, dict) or "storage_identifier" not in document:
        raise NotABagError(f"{source}: not rosbag2 metadata")
    try:
        topics = []
        for entry in document.get("topics_with_message_count") or []:
            meta = entry["topic_metadata"]
            topics.append(
                (
                    TopicInfo(
                        name=str(meta["name"]),
                        type=str(meta["type"]),
                        serialization_format=str(meta.get("serialization_format") or ""),
                        offered_qos_profiles=_qos_text(meta.get("offered_qos_profiles")),
                        type_description_hash=str(meta.get("type_description_hash") or ""),
                    ),
                    int(entry.get("message_count") or 0),
                )
            )
        files = [
            FileInformation(
                path=str(f["path"]),
                starting_time=_int(f.get("starting_time"), "nanoseconds_since_epoch"),
                duration=_int(f.get("duration"), "nanoseconds"),
                message_count=int(f.get("message_count") or 0),
            )
            for f in document.get("files") or []
        ]
        return BagMetadata(
            version=int(document.get("version") or 1),
            storage_identifier=str(document["storage_identifier"] or ""),
            relative_file_paths=[str(p) for p in document.get("relative_file_paths") or []],
            starting_time=_int(document.get("starting_time"), "nanoseconds_since_epoch"),
            duration=_int(document.get("duration"), "nanoseconds"),
            message_count=int(document.get("message_count") or 0),
            topics=topics,
            files=files,
            compression_format=str(document.get("compression_format") or ""),
            compression_mode=str(document.get("compression_mode") or ""),
            custom_data={str(k): str(v) for k, v in (document.get("custom_data") or {}).items()},
            ros_distro=str(document.get("ros_distro") or ""),
        )
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise NotABagError(f"{source}: malformed rosbag2 metadata ({exc})") from exc


def read_metadata(bag_dir: Path) -> BagMetadata | None:
    """Read ``bag_dir/metadata.yaml``; None when the bag has none."""
    path = bag_dir / METADATA_FILENAME
    if not path.is_file():
        return None
    return parse_metadata(path.read_text(encoding="utf-8"), source=str(path))
