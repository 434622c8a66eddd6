"""A bag's storage files: which they are (a bag directory, metadata.yaml's list, a bare
file) and each opened with the back-end its content names, through the compression layer."""

from __future__ import annotations

import re
import shutil
from pathlib import Path
from typing import BinaryIO, cast

from bagkit.bag.compression import (
    Decompression,
    decompressed_copy,
    is_zstd,
    sniff_message_compression,
)
from bagkit.bag.errors import (
    BagError,
    BagNotFoundError,
    CorruptBagError,
    NotABagError,
    UnsupportedStorageError,
)
from bagkit.bag.local_copy import LocalCopy
from bagkit.bag.mcap_file import McapFile
from bagkit.bag.mcapio import DEFAULT_MAX_CHUNK_SIZE, MAGIC
from bagkit.bag.metadata import METADATA_FILENAME, BagMetadata, parse_metadata, read_metadata
from bagkit.bag.storage import ROSBAG1_MAGIC, SQLITE_MAGIC, StorageFile
from bagkit.storage.paths import UrlPath
from bagkit.storage.transfer import local_copy, temporary_directory
from bagkit.storage.urls import is_url

STORAGE_SUFFIXES = (".mcap", ".db3")
# rosbag2's file compression names the compressed files so.
COMPRESSED_STORAGE_SUFFIXES = (".mcap.zstd", ".db3.zstd")
SUPPORTED_STORAGE = ("mcap", "sqlite3")
SUPPORTED_COMPRESSION = ("zstd",)


def _natural_key(path: Path) -> list[int | str]:
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", path.name)]


def listed_file(bag_dir: Path, name: str) -> Path:
    """A file of ``relative_file_paths``; early rosbag2 versions prefixed the bag's own name."""
    path = bag_dir / name
    if not path.exists() and (bag_dir / Path(name).name).exists():
        return bag_dir / Path(name).name
    return path


def is_storage_name(name: str) -> bool:
    """True for the name of a storage file (``.mcap``, ``.db3``, and those zstd-compressed)."""
    return name.endswith(STORAGE_SUFFIXES + COMPRESSED_STORAGE_SUFFIXES)


def bag_path(path: str | Path) -> Path:
    """A bag's path: a ``Path``, or for a URL a :class:`~bagkit.storage.paths.UrlPath`, which has
    the part of Path's API the readers use (the back-ends open it by range requests)."""
    if isinstance(path, UrlPath) or is_url(path):
        return cast(Path, UrlPath(cast(str, path)))
    return Path(path)


def find_storage_files(path: Path) -> tuple[Path, list[Path], BagMetadata | None]:
    """Return (bag directory, storage files, metadata) for a bag path."""
    if not path.exists():
        raise BagNotFoundError(f"{path}: no such file or directory")
    if path.is_file() and path.name == METADATA_FILENAME:
        path = path.parent
    if path.is_file():
        return path.parent, [path], None
    metadata = read_metadata(path)
    if metadata is not None:
        if metadata.storage_identifier not in SUPPORTED_STORAGE:
            raise UnsupportedStorageError(
                f"{path}: storage {metadata.storage_identifier!r} is not supported "
                f"(only {', '.join(SUPPORTED_STORAGE)})"
            )
        if metadata.compression_format not in ("", *SUPPORTED_COMPRESSION):
            raise UnsupportedStorageError(
                f"{path}: rosbag2 {metadata.compression_mode or 'file'} compression "
                f"{metadata.compression_format!r} is not supported"
            )
        # Each file once: a list naming one twice would read its messages twice.
        listed = list(dict.fromkeys(listed_file(path, n) for n in metadata.relative_file_paths))
        existing = [p for p in listed if p.is_file()]
        if existing:
            return path, existing, metadata
        # Listed files gone (renamed bag, converted storage): fall back to what is there.
    found = sorted(
        (p for p in path.iterdir() if is_storage_name(p.name) and p.is_file()),
        key=_natural_key,
    )
    if not found:
        if metadata is not None:
            raise NotABagError(
                f"{path}: none of the files listed in {METADATA_FILENAME} exist "
                f"({', '.join(metadata.relative_file_paths) or 'none listed'})"
            )
        raise NotABagError(f"{path}: not a bag (no metadata.yaml, no .mcap or .db3 file)")
    return path, found, metadata


def _leading_bytes(f: BinaryIO, *, in_storage: bool) -> bytes:
    """What the back-end is chosen by: the file's first bytes; in storage, an MCAP's closing
    magic stands for them (its footer and summary come in the same range request, and its
    header is read only if needed: :meth:`McapFile.open`)."""
    if in_storage and f.seek(0, 2) >= len(MAGIC):
        f.seek(-len(MAGIC), 2)
        if f.read(len(MAGIC)) == MAGIC:
            return MAGIC
        f.seek(0)
    return f.read(len(SQLITE_MAGIC))


def open_storage_file(
    path: Path,
    *,
    check_crc: bool = True,
    max_chunk_size: int = DEFAULT_MAX_CHUNK_SIZE,
    compression_mode: str | None = None,
) -> StorageFile:
    """Open one storage file, its back-end chosen by its content (MCAP, SQLite3 or ROS 1 magic),
    through the compression layer (:mod:`bagkit.bag.compression`) where it is compressed.

    Args:
        path: the file.
        check_crc, max_chunk_size: see :class:`BagReader`.
        compression_mode: ``metadata.yaml``'s (``message`` decompresses each payload); None
            without metadata.yaml: a SQLite3 file's payloads tell.

    Raises:
        NotABagError: neither MCAP, SQLite3 nor ROS 1 (once decompressed); and what the back-end's
            ``open()`` raises.
    """
    with path.open("rb") as f:
        head = _leading_bytes(f, in_storage=isinstance(path, UrlPath))
    source, temporary = path, None
    copied = isinstance(path, UrlPath) and not head.startswith(MAGIC) and not is_zstd(head)
    if copied:  # SQLite3 and ROS 1 back-ends read files on disk only
        temporary = temporary_directory()
        source = local_copy(cast(UrlPath, path), temporary)
    elif is_zstd(head):
        source = decompressed_copy(path)
        temporary = source.parent
        with open(source, "rb") as f:
            head = f.read(len(SQLITE_MAGIC))
    storage: StorageFile | None = None
    try:
        if head.startswith(MAGIC):
            storage = McapFile(source, check_crc=check_crc, max_chunk_size=max_chunk_size)
        elif head == SQLITE_MAGIC:
            from bagkit.bag.sqlite3_file import Sqlite3File

            storage = Sqlite3File(source)
        elif head.startswith(ROSBAG1_MAGIC):
            from bagkit.bag.rosbag1_file import Rosbag1File  # rosbags: only for ROS 1 bags

            storage = Rosbag1File(source, max_chunk_size=max_chunk_size)
        elif path.name.endswith(".zstd"):  # rosbag2's name for a file-compressed storage file
            raise CorruptBagError(f"{path}: not a zstd stream (no zstd frame at its start)")
        else:
            raise NotABagError(f"{path}: neither an MCAP, a SQLite3 nor a ROS 1 bag file")
        storage.open()
        payloads = compression_mode == "message" or (
            compression_mode is None and message_compressed(storage)
        )
        if payloads or (temporary is not None and not copied):
            storage = Decompression(
                storage,
                path,
                payloads=payloads,
                limit=max_chunk_size,
                temporary=None if copied else temporary,
            )
        # Outside the decompression: that sets its payload filter on the back-end itself.
        if copied and temporary is not None:
            storage = cast(StorageFile, LocalCopy(storage, path, temporary))
        return storage
    except BaseException as exc:
        if storage is not None:
            storage.close()
        if temporary is not None:
            shutil.rmtree(temporary, ignore_errors=True)
            if isinstance(exc, BagError):  # name the bag's file, not the temporary copy
                raise type(exc)(str(exc).replace(str(source), str(path))) from None
        raise


def message_compressed(storage: StorageFile) -> bool:
    """Without metadata.yaml, whether payloads are zstd frames: an MCAP file's own rosbag2
    metadata record says (sniffing would read a chunk per topic), a SQLite3 file's last
    message of each topic shows (cheap)."""
    if isinstance(storage, McapFile):
        text = storage.rosbag2_metadata()
        if text is None:
            return False
        try:
            stored = parse_metadata(text, source=f"{storage.path}: its rosbag2 record")
        except NotABagError:
            return False
        return stored.compression_mode == "message"
    return storage.storage_identifier == "sqlite3" and sniff_message_compression(storage)
