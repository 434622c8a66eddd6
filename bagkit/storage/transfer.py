"""Whole objects: a local copy of one that a back-end can only read from disk (SQLite3, ROS 1,
zstd-compressed files), uploads of outputs written locally, and listings of prefixes."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from bagkit.storage.errors import OutputExistsError, StorageError
from bagkit.storage.filesystems import call, filesystem
from bagkit.storage.paths import UrlPath, remember
from bagkit.storage.urls import joined, scheme

# A copy is fetched in pieces of this size (memory stays bounded whatever the object's size).
COPY_PIECE = 8 << 20


def local_copy(path: UrlPath, directory: Path) -> Path:
    """Copy the object at ``path`` into ``directory`` (kept under its name); the caller
    removes the directory.

    Raises:
        StorageError: unreadable, or not enough room for it in ``directory``.
    """
    with path.open() as source:
        free = shutil.disk_usage(directory).free
        if source.size > free:
            raise StorageError(
                f"{path}: {source.size} bytes to copy locally, {free} free in {directory}"
            )
        target = directory / path.name
        with open(target, "wb") as out:
            while piece := source.read(COPY_PIECE):
                out.write(piece)
    return target


def temporary_directory() -> Path:
    """A new private directory for local copies (the caller removes it)."""
    import tempfile  # bags in storage only: a command on a local bag starts without it

    return Path(tempfile.mkdtemp(prefix="bagkit-storage-"))


def upload(local: Path, url: str) -> None:
    """Put the file or directory ``local`` at ``url`` (a directory's files under the prefix)."""
    fs, path = filesystem(url)
    if local.is_dir():
        for file in sorted(p for p in local.rglob("*") if p.is_file()):
            target = joined(path, file.relative_to(local).as_posix())
            _put(fs, url, file, target)
    else:
        _put(fs, url, local, path)


def _put(fs: Any, url: str, local: Path, target: str) -> None:
    call(url, lambda: fs.put_file(str(local), target))


@contextmanager
def written_to(output: Path, *, replace: bool = False, update: bool = False) -> Iterator[Path]:
    """Where a command writes ``output``: itself, or for a URL (a UrlPath) a local temporary
    path, uploaded to the URL when the block ends without an error.

    Args:
        output: the output as given.
        replace: an object already at the URL may be replaced (``output.force``); else an
            error.
        update: the output is updated in place (a catalogue): what is at the URL is fetched
            first.

    Raises:
        StorageError: the URL exists (without ``replace``), or the upload failed.
    """
    if not isinstance(output, UrlPath):
        yield output
        return
    directory = temporary_directory()
    try:
        local = directory / output.name
        if output.exists():
            if update and output.is_file():
                local = local_copy(output, directory)
            elif not (replace or update):
                raise OutputExistsError(f"{output} exists", "output.force")
        yield local
        # What the command wrote beside it too (a catalogue's events file) goes beside it.
        for written in sorted(directory.iterdir()):
            upload(written, joined(output.parent.url, written.name))
    finally:
        shutil.rmtree(directory, ignore_errors=True)


@contextmanager
def read_from(path: Path, *beside: str) -> Iterator[Path]:
    """Where a command reads the file ``path``: itself, or for a URL (a UrlPath) a local copy
    (with the objects named ``beside`` that exist next to it, copied next to it), removed
    when the block ends; a URL with no object is a local path that does not exist.

    Raises:
        StorageError: the object cannot be read.
    """
    if not isinstance(path, UrlPath):
        yield path
        return
    directory = temporary_directory()
    try:
        if not path.is_file():
            yield directory / path.name
            return
        local = local_copy(path, directory)
        for name in beside:
            if (path.parent / name).is_file():
                local_copy(path.parent / name, directory)
        yield local
    finally:
        shutil.rmtree(directory, ignore_errors=True)


@contextmanager
def local_folders(paths: list[Path]) -> Iterator[list[Path]]:
    """``paths`` with each prefix in storage (a UrlPath) replaced by a local copy of the
    objects under it (named as the prefix), removed when the block ends; local paths as
    given. For inputs read as folders of files (golden fixtures).

    Raises:
        StorageError: a prefix cannot be listed (HTTP lists none) or an object read.
    """
    directory = temporary_directory()
    try:
        found: list[Path] = []
        for index, path in enumerate(paths):
            if not isinstance(path, UrlPath):
                found.append(path)
                continue
            if scheme(path.url) in ("http", "https"):
                raise StorageError(f"{path}: an HTTP server lists no prefixes to copy")
            target = directory / str(index) / path.name
            for item in objects_under(path):
                folder = target / item.relative_to(path)
                folder.parent.mkdir(parents=True, exist_ok=True)
                local_copy(item, folder.parent)
            if not target.is_dir():
                raise StorageError(f"{path}: no object under this prefix")
            found.append(target)
        yield found
    finally:
        shutil.rmtree(directory, ignore_errors=True)


def shown_path(path: Path, local: Path, output: Path) -> str:
    """How ``path``, written under ``local`` (what :func:`written_to` gave for ``output``), is
    named to the user: under ``output``'s URL when it is one (shown without secrets)."""
    if not isinstance(output, UrlPath) or not path.is_relative_to(local):
        return str(path)
    relative = path.relative_to(local).as_posix()
    return str(output / relative if relative != "." else output)


def objects_under(prefix: UrlPath) -> Iterator[UrlPath]:
    """Every object under ``prefix`` (one listing request per page), remembered for opening."""
    fs, path = filesystem(prefix.url)
    found = call(prefix.url, lambda: fs.find(path, detail=True))
    base = path.rstrip("/")
    for name in sorted(found):
        relative = name[len(base) + 1 :] if name.startswith(base + "/") else None
        if relative is None:
            continue
        url = joined(prefix.url, relative)
        remember(url, found[name])
        yield UrlPath(url)
