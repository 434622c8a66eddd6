"""A rosbag2 SQLite3 bag as the output of a copy, written by rosbags' rosbag2 writer.

rosbags writes rosbag2's schema (``topics`` with QoS and type hash, ``message_definitions``,
``messages``) and ``metadata.yaml`` version 9, and compresses with zstd per message or per
file as rosbag2 does. As :class:`~bagkit.surgery.output.OutputBag`, nothing appears under the
output name before :meth:`Sqlite3OutputBag.commit`: the bag is written inside a hidden
sibling directory and moved into place.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from rosbags.interfaces import Connection, Qos
from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
from rosbags.rosbag2.metadata import parse_qos

from bagkit.bag.definitions import UNKNOWN_ENCODING
from bagkit.bag.messages import BagMessage, TopicInfo
from bagkit.surgery.errors import SurgeryError
from bagkit.surgery.options import OutputOptions
from bagkit.surgery.output_paths import check_replaceable

_MODES = {"message": CompressionMode.MESSAGE, "file": CompressionMode.FILE}


class Sqlite3OutputBag:
    """A rosbag2 SQLite3 bag written message by message (a
    :class:`~bagkit.surgery.output.MessageOutput`).

    Raises:
        SurgeryError: ``path`` exists without ``force``, its parent does not, or the options
            ask what a SQLite3 bag cannot do (lz4, splitting).
    """

    def __init__(self, path: Path, options: OutputOptions) -> None:
        if options.compression not in ("zstd", "none"):
            raise SurgeryError(
                f"{options.compression}: rosbag2 compresses sqlite3 bags with zstd only "
                "(zstd or none)",
                "output.compression",
            )
        if options.compression == "zstd" and options.compression_mode not in _MODES:
            raise SurgeryError(f"compression mode {options.compression_mode!r}: message or file")
        if options.max_bag_size or options.max_bag_duration_s:
            raise SurgeryError(
                "a sqlite3 output is not split", "output.max_bag_size, output.max_bag_duration_s"
            )
        if not path.name or path.name == "..":
            raise SurgeryError(f"{str(path)!r} names no bag directory to write")
        if path.exists() or path.is_symlink():
            if not options.force:
                raise SurgeryError(f"{path} already exists", "output.force")
            check_replaceable(path)
        if not path.parent.is_dir():
            raise SurgeryError(f"{path.parent}: no such directory")
        self.path = path
        # rosbags names the database after its directory: the bag is written as temp/NAME.
        self._temp = path.parent / f".{path.name}.partial-{os.getpid()}"
        shutil.rmtree(self._temp, ignore_errors=True)
        self._temp.mkdir()
        self._writer = Writer(
            self._temp / path.name, version=9, storage_plugin=StoragePlugin.SQLITE3
        )
        if options.compression == "zstd":
            self._writer.set_compression(_MODES[options.compression_mode], CompressionFormat.ZSTD)
        self._writer.open()
        self._connections: dict[str, Connection] = {}
        self._by_id: dict[int, Connection] = {}
        self.counts: dict[int, int] = {}
        self.custom_data: dict[str, str] = {}

    def add_topic(self, topic: TopicInfo, definition: str | None, preferred_id: int) -> int:
        """Add a topic (once per name) with its definition, QoS and type hash; return its id.
        A definition not known (None) is written as rosbag2 writes it: encoding ``unknown``, no
        text, no type hash made up."""
        known = self._connections.get(topic.name)
        if known is not None:
            return known.id
        try:
            qos = parse_qos(topic.offered_qos_profiles) if topic.offered_qos_profiles else []
        except Exception:
            qos = []
        type_hash = topic.type_description_hash
        if definition is not None and not type_hash:
            type_hash = _type_hash(topic, definition)
        if definition is not None and type_hash:
            connection = self._writer.add_connection(
                topic.name,
                topic.type,
                msgdef=definition,
                rihs01=type_hash,
                serialization_format=topic.serialization_format or "cdr",
                offered_qos_profiles=qos,
            )
        else:
            connection = self._without_hash(topic, qos, definition)
        self._connections[topic.name] = connection
        self._by_id[connection.id] = connection
        self.counts[connection.id] = 0
        return connection.id

    def _without_hash(self, topic: TopicInfo, qos: list[Qos], definition: str | None) -> Connection:
        """A connection without a type hash: its definition is not known (None), or names types
        it does not define (rosbag2's test bags store such stubs). rosbags' writer takes a text
        and a hash only, so its rows are set afterwards as rosbag2 writes them (no hash; an
        unknown definition's encoding ``unknown``, without text), and the connection (which
        metadata.yaml is written from) keeps the topic's own hash, empty when it has none."""
        added = self._writer.add_connection(
            topic.name,
            topic.type,
            msgdef=definition or "",
            rihs01=topic.type_description_hash or "unknown",
            serialization_format=topic.serialization_format or "cdr",
            offered_qos_profiles=qos,
        )
        connection = added._replace(digest=topic.type_description_hash)
        connections = self._writer.connections
        connections[connections.index(added)] = connection
        conn = self._writer.storage.conn  # type: ignore[union-attr]
        if definition is None:
            conn.execute(
                "UPDATE message_definitions SET encoding = ?, type_description_hash = '' "
                "WHERE topic_type = ? AND encoded_message_definition = ''",
                (UNKNOWN_ENCODING, topic.type),
            )
        else:
            conn.execute(
                "UPDATE message_definitions SET type_description_hash = '' "
                "WHERE topic_type = ? AND encoded_message_definition = ?",
                (topic.type, definition),
            )
        conn.execute(
            "UPDATE topics SET type_description_hash = ? WHERE name = ?",
            (topic.type_description_hash, topic.name),
        )
        return connection

    def topic_id(self, topic: str) -> int:
        """The id of a topic added."""
        return self._connections[topic].id

    def write_message(self, channel_id: int, message: BagMessage, log_time: int) -> None:
        """Append one message (SQLite3 keeps one time per message: ``log_time``)."""
        self._writer.write(self._by_id[channel_id], log_time, message.data)
        self.counts[channel_id] += 1

    def write_messages(self, channel_ids: list[int], messages: list[BagMessage]) -> None:
        """Append messages at their log times, each under its id of ``channel_ids``."""
        for channel_id, message in zip(channel_ids, messages, strict=True):
            self.write_message(channel_id, message, message.log_time)

    def commit(self) -> list[Path]:
        """Close the database and metadata.yaml, move the bag into place; return its files."""
        for key, value in self.custom_data.items():
            self._writer.set_custom_data(key, value)
        try:
            self._writer.close()
        except (WriterError, OSError) as exc:
            raise SurgeryError(f"{self.path}: cannot finish the sqlite3 bag ({exc})") from exc
        if self.path.exists() or self.path.is_symlink():
            if self.path.is_dir() and not self.path.is_symlink():
                shutil.rmtree(self.path)
            else:
                self.path.unlink()
        (self._temp / self.path.name).rename(self.path)
        self._temp.rmdir()
        return sorted(p for p in self.path.iterdir() if p.name != "metadata.yaml")

    def abort(self) -> None:
        """Remove what was written (the output name is left untouched)."""
        storage = self._writer.storage
        if storage is not None:
            storage.conn.close()  # type: ignore[attr-defined]
        shutil.rmtree(self._temp, ignore_errors=True)


def _type_hash(topic: TopicInfo, definition: str) -> str:
    """The RIHS01 hash of a topic's type from its definition (older bags store none); empty
    when the definition does not give one (it names a type it does not define)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    try:
        store = get_typestore(Stores.EMPTY)
        store.register(get_types_from_msg(definition, topic.type))
        return store.hash_rihs01(topic.type)
    except Exception:
        return ""
