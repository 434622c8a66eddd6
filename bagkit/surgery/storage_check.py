"""``doctor``'s check of a storage file that is not a plain MCAP file: a SQLite3 ``.db3``, a
ROS 1 ``.bag``, or a zstd-compressed ``.db3.zstd``/``.mcap.zstd`` (rosbag2's compression).

Read through the bag back-ends (:func:`bagkit.bag.storage_files.open_storage_file`, compression
included), described as the MCAP walk describes a file (:class:`FileFacts`: one schema per
type, one channel per topic), so that the bag-level checks (metadata.yaml, decodability) are
the same. A SQLite3 database is also checked whole (``PRAGMA quick_check``), a ROS 1 bag's
chunks walked record by record against its index (chunk infos, index data, connections).
"""

from __future__ import annotations

import sqlite3
from collections.abc import Callable
from pathlib import Path

from bagkit.bag.compression import Decompression
from bagkit.bag.definitions import definition_encoding
from bagkit.bag.mcapio.records import Channel, Schema
from bagkit.bag.sqlite3_file import connect
from bagkit.bag.storage import StorageFile
from bagkit.bag.storage_files import open_storage_file
from bagkit.surgery.file_check import FileFacts, MessageCheck

# At most this many lines of SQLite3's own report.
MAX_INTEGRITY_LINES = 5


def check_storage_file(
    file: Path,
    compression_mode: str | None,
    check_for: Callable[[FileFacts], MessageCheck | None] | None = None,
) -> FileFacts:
    """The facts of ``file`` and what is wrong with it.

    Args:
        file: the storage file.
        compression_mode: ``metadata.yaml``'s (None without one).
        check_for: given the file's facts (schemas, channels), the check each message is then
            given to (``channel_id, log_time, payload``), or None.

    Raises:
        BagError: the file cannot be opened at all (not a bag, unreadable).
    """
    storage = open_storage_file(file, compression_mode=compression_mode)
    try:
        facts = _facts(storage)
        if storage.storage_identifier == "sqlite3":
            inner = storage.inner if isinstance(storage, Decompression) else storage
            facts.problems.extend(quick_check(inner.path))
        elif storage.storage_identifier == "rosbag1":
            from bagkit.bag.rosbag1_file import Rosbag1File  # rosbags: only for .bag files

            if isinstance(storage, Rosbag1File):
                facts.problems.extend(storage.check_index())
        check_message = check_for(facts) if check_for is not None else None
        if check_message is not None:
            ids = {c.topic: c.id for c in facts.channels.values()}
            for message in storage.messages(None, None, None):
                check_message(ids[message.topic], message.log_time, memoryview(message.data))
        facts.problems.extend(p.removeprefix(f"{file.name}: ") for p in storage.problems)
    finally:
        storage.close()
    return facts


def _facts(storage: StorageFile) -> FileFacts:
    facts = FileFacts()
    schema_ids: dict[str, int] = {}
    for channel_id, (name, topic) in enumerate(sorted(storage.topics.items()), start=1):
        schema_id = schema_ids.get(topic.type)
        if schema_id is None:
            # A type without a stored text gets a schema naming it only (encoding ""): the
            # decodability check then takes it where the read commands do.
            text = storage.definitions.get(topic.type)
            schema_id = schema_ids[topic.type] = len(schema_ids) + 1
            facts.schemas[schema_id] = Schema(
                id=schema_id,
                name=topic.type,
                encoding="" if text is None else definition_encoding(text),
                data=b"" if text is None else text.encode("utf-8"),
            )
        facts.channels[channel_id] = Channel(
            id=channel_id,
            schema_id=schema_id,
            topic=name,
            message_encoding=topic.serialization_format,
            metadata={},
        )
        facts.counts[channel_id] = storage.topic_counts.get(name, 0)
    if any(facts.counts.values()):
        facts.start, facts.end = storage.start_ns, storage.end_ns
    return facts


def quick_check(path: Path) -> list[str]:
    """SQLite3's ``PRAGMA quick_check`` of the database at ``path``: its problems, one each."""
    db = connect(path)
    try:
        rows = db.execute(f"PRAGMA quick_check({MAX_INTEGRITY_LINES})").fetchall()
    except sqlite3.Error as exc:
        return [f"SQLite3 integrity check failed ({exc})"]
    finally:
        db.close()
    lines = [str(row[0]) for row in rows]
    return [] if lines == ["ok"] else [f"SQLite3 integrity: {line}" for line in lines]
