"""rosbag2's ``metadata.yaml``: write version 9 (Jazzy), read versions 1 to 9."""

from __future__ import annotations

import contextlib
import datetime
import re
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

import yaml

from bagkit.bag import safe_yaml
from bagkit.bag.errors import NotABagError
from bagkit.bag.messages import TopicInfo

METADATA_FILENAME = "metadata.yaml"
METADATA_VERSION = 9
ROS_DISTRO = "jazzy"
_ROOT_KEY = "rosbag2_bagfile_information"
MAX_METADATA_BYTES = safe_yaml.MAX_YAML_BYTES
_INT64_MIN = -(1 << 63)
_UINT64_MAX = (1 << 64) - 1
_DIGITS = re.compile(r"-?[0-9]{1,20}")


@dataclass(frozen=True, slots=True)
class FileInformation:
    """One storage file of a bag, as listed under ``files``."""

    path: str
    starting_time: int
    duration: int
    message_count: int


@dataclass(slots=True)
class BagMetadata:
    """The content of ``metadata.yaml`` (``rosbag2_bagfile_information``).

    ``compression_mode`` is in lower case (``file``, ``message`` or empty): rosbag2 writes
    ``FILE``/``MESSAGE`` and reads it in any case, rosbags writes ``file``/``message``.
    """

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
                        "offered_qos_profiles": _qos_for_version(
                            topic.offered_qos_profiles, self.version
                        ),
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


class _MalformedError(Exception):
    """A field of the wrong type or out of range; parse_metadata names the file."""


def _scalar_text(value: Any, where: str) -> str:
    """A string field: YAML may have typed a plain scalar (``name: 123``), never a collection."""
    if value is None:
        return ""
    if isinstance(value, (str, int, float, datetime.date)):
        return str(value)
    raise _MalformedError(f"{where}: expected a string, found {type(value).__name__}")


def _integer(value: Any, where: str, low: int, high: int) -> int:
    """An integer field (plain or quoted digits) within ``low..high``; None counts as 0."""
    if value is None:
        return 0
    if isinstance(value, str) and _DIGITS.fullmatch(value):
        value = int(value)
    if not isinstance(value, int) or isinstance(value, bool):
        raise _MalformedError(f"{where}: expected an integer, found {value!r:.40}")
    if not low <= value <= high:
        raise _MalformedError(f"{where}: {value} out of range {low}..{high}")
    return value


def _mapping(value: Any, where: str) -> dict[Any, Any]:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise _MalformedError(f"{where}: expected a mapping, found {type(value).__name__}")
    return value


def _sequence(value: Any, where: str) -> list[Any]:
    if value is None:
        return []
    if not isinstance(value, list):
        raise _MalformedError(f"{where}: expected a list, found {type(value).__name__}")
    return value


def _time(node: Any, key: str, where: str, low: int = _INT64_MIN) -> int:
    """``{key: N}`` as rosbag2 writes times and durations (a bare integer is accepted too)."""
    if isinstance(node, dict):
        return _integer(node.get(key), f"{where}.{key}", low, _UINT64_MAX)
    return _integer(node, where, low, _UINT64_MAX)


def _qos_text(value: Any, where: str) -> str:
    """Offered QoS profiles: a YAML string, or (some writers) the profiles themselves."""
    if isinstance(value, (list, dict)):
        return yaml.safe_dump(value, sort_keys=False, default_flow_style=False)
    return _scalar_text(value, where)


def _qos_for_version(text: str, version: int) -> Any:
    """Offered QoS profiles as rosbag2 stores them in metadata of ``version``.

    rosbag2 (Jazzy on) writes and reads version 9 profiles as a YAML sequence and rejects a
    string there (``ros2 bag info`` fails, as does its MCAP plugin on the ``rosbag2`` record);
    versions 4 to 8 hold the YAML string. Text that is not a list of profiles (carried from
    an untrusted bag) stays a string, not lost.
    """
    if version < 9:
        return text
    if not text.strip():
        return []
    try:
        profiles = safe_yaml.load(text)
    except yaml.YAMLError:
        return text
    return profiles if isinstance(profiles, list) else text


def _relative_path(value: Any, where: str) -> str:
    """A file of the bag: relative, inside the bag directory (no ``..``), no NUL."""
    path = _scalar_text(value, where)
    pure = PurePosixPath(path)
    if not path or "\x00" in path or pure.is_absolute() or ".." in pure.parts:
        raise _MalformedError(f"{where}: {path!r:.80} is not a path inside the bag directory")
    return path


def _topic(entry: Any, where: str) -> tuple[TopicInfo, int]:
    entry = _mapping(entry, where)
    meta = _mapping(entry.get("topic_metadata"), f"{where}.topic_metadata")
    if "name" not in meta or "type" not in meta:
        raise _MalformedError(f"{where}.topic_metadata: name or type missing")
    field = f"{where}.topic_metadata"
    info = TopicInfo(
        name=_scalar_text(meta["name"], f"{field}.name"),
        type=_scalar_text(meta["type"], f"{field}.type"),
        serialization_format=_scalar_text(
            meta.get("serialization_format"), f"{field}.serialization_format"
        ),
        offered_qos_profiles=_qos_text(
            meta.get("offered_qos_profiles"), f"{field}.offered_qos_profiles"
        ),
        type_description_hash=_scalar_text(
            meta.get("type_description_hash"), f"{field}.type_description_hash"
        ),
    )
    count = _integer(entry.get("message_count"), f"{where}.message_count", 0, _UINT64_MAX)
    return info, count


def _file(entry: Any, where: str) -> FileInformation:
    entry = _mapping(entry, where)
    return FileInformation(
        path=_relative_path(entry.get("path"), f"{where}.path"),
        starting_time=_time(
            entry.get("starting_time"), "nanoseconds_since_epoch", f"{where}.starting_time"
        ),
        duration=_time(entry.get("duration"), "nanoseconds", f"{where}.duration"),
        message_count=_integer(
            entry.get("message_count"), f"{where}.message_count", 0, _UINT64_MAX
        ),
    )


def _metadata(document: dict[Any, Any]) -> BagMetadata:
    """The fields of ``rosbag2_bagfile_information``, each checked for type and range."""
    topics = document.get("topics_with_message_count")
    files = document.get("files")
    paths = document.get("relative_file_paths")
    custom = _mapping(document.get("custom_data"), "custom_data")
    return BagMetadata(
        version=_integer(document.get("version"), "version", 0, 1000) or 1,
        storage_identifier=_scalar_text(document["storage_identifier"], "storage_identifier"),
        relative_file_paths=[
            _relative_path(p, f"relative_file_paths[{i}]")
            for i, p in enumerate(_sequence(paths, "relative_file_paths"))
        ],
        starting_time=_time(
            document.get("starting_time"), "nanoseconds_since_epoch", "starting_time"
        ),
        duration=_time(document.get("duration"), "nanoseconds", "duration"),
        message_count=_integer(document.get("message_count"), "message_count", 0, _UINT64_MAX),
        topics=[
            _topic(t, f"topics_with_message_count[{i}]")
            for i, t in enumerate(_sequence(topics, "topics_with_message_count"))
        ],
        files=[_file(f, f"files[{i}]") for i, f in enumerate(_sequence(files, "files"))],
        compression_format=_scalar_text(document.get("compression_format"), "compression_format"),
        compression_mode=_scalar_text(document.get("compression_mode"), "compression_mode").lower(),
        custom_data={
            _scalar_text(k, "custom_data key"): _scalar_text(v, f"custom_data[{k!r:.40}]")
            for k, v in custom.items()
        },
        ros_distro=_scalar_text(document.get("ros_distro"), "ros_distro"),
    )


def parse_metadata(text: str, *, source: str = METADATA_FILENAME) -> BagMetadata:
    """Parse ``metadata.yaml`` content of any rosbag2 version (1 to 9), as untrusted input.

    Limits (:mod:`bagkit.bag.safe_yaml`): size, nesting depth, node count, no aliases; every
    field is checked for its type and range; file paths must stay inside the bag directory.

    Raises:
        NotABagError: not YAML, beyond a limit, or not (well-formed) rosbag2 metadata.
    """
    try:
        document = safe_yaml.load(text)
    except safe_yaml.YamlLimitError as exc:
        raise NotABagError(f"{source}: YAML refused: {exc}") from None
    except yaml.YAMLError as exc:
        raise NotABagError(f"{source}: not valid YAML ({_one_line(exc)})") from None
    if isinstance(document, dict) and _ROOT_KEY in document:
        document = document[_ROOT_KEY]
    if not isinstance(document, dict) or "storage_identifier" not in document:
        raise NotABagError(f"{source}: not rosbag2 metadata")
    try:
        return _metadata(document)
    except _MalformedError as exc:
        raise NotABagError(f"{source}: malformed rosbag2 metadata: {exc}") from None


def _one_line(exc: Exception) -> str:
    """A YAML error on one line (libyaml's spread over several, with a source excerpt)."""
    return " ".join(str(exc).split())


def _check_inside(bag_dir: Path, names: list[str], source: str) -> None:
    """Refuse listed files that resolve outside the bag directory (through symlinks).

    Both places the reader looks are checked: the path as listed, and its base name (early
    rosbag2 versions prefixed the bag's own name). A bag in storage (a UrlPath: no symlinks
    there) refuses absolute names and ``..``.
    """
    if not isinstance(bag_dir, Path):
        for name in names:
            if name.startswith("/") or ".." in PurePosixPath(name).parts:
                raise NotABagError(f"{source}: {name!r} leaves the bag's prefix")
        return
    try:
        root = bag_dir.resolve()
        for name in names:
            for candidate in (bag_dir / name, bag_dir / PurePosixPath(name).name):
                if candidate.is_symlink() and not candidate.exists():
                    _raise_on_loop(candidate)  # Python 3.13's resolve() lets a loop through
                present = candidate.is_symlink() or candidate.exists()
                if present and not candidate.resolve().is_relative_to(root):
                    raise NotABagError(f"{source}: {name!r} resolves outside the bag directory")
    except (OSError, RuntimeError) as exc:  # RuntimeError: a symlink loop (Python 3.10-3.12)
        raise NotABagError(f"{source}: cannot resolve the listed files ({exc})") from exc


def _raise_on_loop(link: Path) -> None:
    """Raise OSError or RuntimeError when ``link`` is a symlink loop; a dangling link passes."""
    with contextlib.suppress(FileNotFoundError):
        link.resolve(strict=True)


def read_metadata(bag_dir: Path) -> BagMetadata | None:
    """Read ``bag_dir/metadata.yaml`` (at most ``MAX_METADATA_BYTES``); None when there is none.

    Raises:
        NotABagError: unreadable, too large, not UTF-8, malformed (see :func:`parse_metadata`), or
            a listed file that leaves the bag directory.
    """
    path = bag_dir / METADATA_FILENAME
    if not path.is_file():
        return None
    try:
        with path.open("rb") as f:
            raw = f.read(MAX_METADATA_BYTES + 1)
    except OSError as exc:
        raise NotABagError(f"{path}: cannot read ({exc.strerror or exc})") from exc
    if len(raw) > MAX_METADATA_BYTES:
        raise NotABagError(f"{path}: larger than {MAX_METADATA_BYTES} bytes, not a metadata.yaml")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise NotABagError(f"{path}: not UTF-8 (byte {exc.start})") from None
    metadata = parse_metadata(text, source=str(path))
    _check_inside(bag_dir, metadata.relative_file_paths, str(path))
    return metadata
