"""``convert``: bags of any storage into a rosbag2 MCAP or SQLite3 bag, and ``ros2 bag
convert``'s options file.

Convert is ``filter`` (one input) or ``merge`` (several) with a chosen output storage and
compression: MCAP inputs into MCAP are copied chunk by chunk (recompressed where the
compression differs), anything else message by message (:mod:`~bagkit.surgery.message_copy`).

``ros2 bag convert -o OPTIONS.yaml`` takes ``output_bags:``, a list of rosbag2 storage and
record options per output bag (rosbag2's README, "Converting bags"); the keys that map onto
bagkit's selection and output are read, keys left at their defaults are accepted, and a key
asking what bagkit does not do is refused by name.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from bagkit.bag import safe_yaml
from bagkit.surgery.content import with_content
from bagkit.surgery.errors import SurgeryError
from bagkit.surgery.message_copy import Progress, rewrite_messages
from bagkit.surgery.rewrite import (
    OutputOptions,
    RewriteReport,
    check_output,
    chunks_copyable,
    filter_bag,
    merge_bags,
)
from bagkit.surgery.select import Selection

STORAGES = ("mcap", "sqlite3")
_SERVICE_EVENTS = "/_service_event$"
# Keys of rosbag2's StorageOptions/RecordOptions that change nothing in a conversion here when
# left at their defaults (and what their defaults are).
_INERT: dict[str, object] = {
    "storage_config_uri": "",
    "compression_queue_size": None,
    "compression_threads": None,
    "compression_threads_priority": None,
    "include_hidden_topics": None,
    "include_unpublished_topics": None,
    "snapshot_mode": False,
    "snapshot_duration": None,
    "max_cache_size": None,
    "ignore_leaf_topics": None,
    "rmw_serialization_format": ("", "cdr"),
    "topic_types": ([],),
    "exclude_topic_types": ([],),
    "custom_data": ({},),
    "start_paused": False,
    "use_sim_time": False,
    "node_prefix": "",
    "is_discovery_disabled": None,
    "topic_polling_interval": None,
}
_MAPPED = {
    "uri",
    "storage_id",
    "max_bagfile_size",
    "max_bagfile_duration",
    "storage_preset_profile",
    "all_topics",
    "topics",
    "regex",
    "exclude_regex",
    "exclude_topics",
    "all_services",
    "services",
    "exclude_services",
    "compression_mode",
    "compression_format",
    "start_time_ns",
    "end_time_ns",
}


def convert_bags(
    bags: Sequence[Path],
    output: Path,
    selection: Selection | None = None,
    options: OutputOptions | None = None,
    progress: Progress | None = None,
) -> RewriteReport:
    """Write the selected messages of ``bags`` (merged in log-time order) to a new bag
    ``output`` in ``options.storage`` with ``options.compression``.

    Args:
        progress: called with (messages done, messages in all) while copying message by
            message (the chunk copy of MCAP into MCAP is not counted).

    Raises:
        BagError: an input cannot be opened. SurgeryError: see :func:`filter_bag`.
    """
    if not bags:
        raise SurgeryError("no input bag")
    selection = selection or Selection()
    options = options or OutputOptions()
    check_output(bags, output, options)
    selection = with_content(bags, selection)
    if options.storage == "mcap" and chunks_copyable(bags):
        if len(bags) == 1:
            return filter_bag(bags[0], output, selection, options)
        return merge_bags(bags, output, selection, options)
    return rewrite_messages(bags, output, selection, options, progress)


@dataclass(frozen=True)
class OutputBagSpec:
    """One entry of ``output_bags``: where, what and how."""

    uri: Path
    selection: Selection
    options: OutputOptions


def read_output_options(path: Path, *, force: bool = False) -> list[OutputBagSpec]:
    """The output bags of a ``ros2 bag convert`` options file (relative URIs: from the
    working directory, as ``ros2 bag convert`` takes them).

    Raises:
        SurgeryError: unreadable, not ``output_bags: [...]``, or a key bagkit cannot honour.
    """
    try:
        document = safe_yaml.load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise SurgeryError(f"{path}: unreadable options file ({exc})") from None
    bags = document.get("output_bags") if isinstance(document, dict) else None
    if not isinstance(bags, list) or not bags:
        raise SurgeryError(f"{path}: needs a top-level key output_bags with a list of bags")
    return [_spec(entry, f"{path}: output_bags[{n}]", force) for n, entry in enumerate(bags)]


def _spec(entry: Any, where: str, force: bool) -> OutputBagSpec:
    if not isinstance(entry, dict):
        raise SurgeryError(f"{where} is not a mapping")
    for key, value in entry.items():
        if key in _MAPPED:
            continue
        if key not in _INERT:
            raise SurgeryError(f"{where}: unknown key {key!r}")
        default = _INERT[key]
        if default is not None and value not in (
            default if isinstance(default, tuple) else (default,)
        ):
            raise SurgeryError(f"{where}: {key}: {value!r} is not supported by bagkit convert")
    uri = _text(entry, "uri", where, "")
    if not uri:
        raise SurgeryError(f"{where}: uri is required")
    storage = _text(entry, "storage_id", where, "") or "mcap"
    if storage not in STORAGES:
        raise SurgeryError(f"{where}: storage_id {storage!r}: bagkit writes mcap or sqlite3")
    return OutputBagSpec(
        Path(uri), _selection(entry, where), _options(entry, where, storage, force)
    )


def _selection(entry: dict[str, Any], where: str) -> Selection:
    topics = _names(entry, "topics", where)
    topics += [f"{s.rstrip('/')}/_service_event" for s in _names(entry, "services", where)]
    excluded = _names(entry, "exclude_topics", where)
    excluded += [
        f"{s.rstrip('/')}/_service_event" for s in _names(entry, "exclude_services", where)
    ]
    regex = _text(entry, "regex", where, "")
    if entry.get("all_topics") is True:
        regex = ".*"
    elif entry.get("all_services") is True:
        regex = f"(?:{regex})|{_SERVICE_EVENTS}" if regex else _SERVICE_EVENTS
    if not topics and not regex:
        raise SurgeryError(
            f"{where} selects no topic (all_topics, topics, regex, all_services or services)"
        )
    start, end = (entry.get(k) for k in ("start_time_ns", "end_time_ns"))
    return Selection.create(
        topics,
        regex,
        excluded,
        _text(entry, "exclude_regex", where, ""),
        _time(start, where) if start not in (None, -1, 0) else None,
        _time(end, where) if end not in (None, -1, 0) else None,
    )


def _options(entry: dict[str, Any], where: str, storage: str, force: bool) -> OutputOptions:
    compression = _text(entry, "compression_format", where, "") or "none"
    preset = _text(entry, "storage_preset_profile", where, "")
    if preset in ("zstd_fast", "zstd_small"):
        compression = "zstd"
    elif preset not in ("", "none", "fastwrite", "resilient"):
        raise SurgeryError(f"{where}: storage_preset_profile {preset!r} is not supported")
    if compression not in ("zstd", "lz4", "none"):
        raise SurgeryError(f"{where}: compression_format {compression!r}: zstd or none")
    mode = _text(entry, "compression_mode", where, "").lower() or "message"
    size = entry.get("max_bagfile_size", 0) or 0
    duration = entry.get("max_bagfile_duration", 0) or 0
    if not isinstance(size, int) or not isinstance(duration, int | float):
        raise SurgeryError(f"{where}: max_bagfile_size and max_bagfile_duration are numbers")
    return OutputOptions(
        compression=compression,
        max_bag_size=size,
        max_bag_duration_s=float(duration),
        force=force,
        storage=storage,
        compression_mode=mode,
    )


def _text(entry: dict[str, Any], key: str, where: str, default: str) -> str:
    value = entry.get(key, default)
    if value is None:
        return default
    if not isinstance(value, str):
        raise SurgeryError(f"{where}: {key} must be text, not {value!r:.40}")
    return value


def _names(entry: dict[str, Any], key: str, where: str) -> list[str]:
    value = entry.get(key) or []
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise SurgeryError(f"{where}: {key} must be a list of names")
    return list(value)


def _time(value: Any, where: str) -> str:
    if not isinstance(value, int) or isinstance(value, bool):
        raise SurgeryError(f"{where}: start_time_ns and end_time_ns are integers")
    return f"{value}ns"
