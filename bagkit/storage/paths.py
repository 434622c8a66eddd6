""":class:`UrlPath`: an object or prefix in storage with the part of ``pathlib.Path``'s API that
the bag readers use, so a bag in a bucket is opened by the same code as one on disk.

Shown (``str``) without secrets; the full URL is ``.url``. Sizes and ETags that a listing
already gave are remembered (:func:`remember`), so a bag found by listing its prefix is opened
without a HEAD request per file.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import Any

from bagkit.storage.errors import BucketNotFoundError, ObjectNotFoundError, StorageError
from bagkit.storage.filesystems import call, filesystem
from bagkit.storage.range_file import RangeFile, found_by_suffix
from bagkit.storage.urls import joined, name, parent, scheme, shown_url

_infos: dict[str, dict[str, Any]] = {}
# The objects whose info comes from a read of their end (what info and catalog read first).
SUFFIX_READ = (".mcap", ".yaml")
# Listings remembered at most (a prefix of a million objects must not fill the memory).
MAX_REMEMBERED = 200_000


def remember(url: str, info: dict[str, Any]) -> None:
    """Keep what a listing said of the object at ``url`` (its size, ETag, type)."""
    if len(_infos) < MAX_REMEMBERED:
        _infos[url.rstrip("/")] = info


def remembered_size(url: str) -> int:
    """Bytes of the object at ``url``, or of the objects under it, as listings said (0 when
    none did)."""
    url = url.rstrip("/")
    known = _infos.get(url)
    if known is not None and known.get("type") != "directory":
        return int(known.get("size") or 0)
    below = url + "/"
    return sum(int(i.get("size") or 0) for u, i in _infos.items() if u.startswith(below))


def stamp(url: str) -> tuple[int, int]:
    """(bytes, latest modification in ns) of the object at ``url`` or the objects under it, as
    listings said (one listing when none did yet): what changes when a bag in storage does."""
    url = url.rstrip("/")
    below = url + "/"
    found = [i for u, i in _infos.items() if u == url or u.startswith(below)]
    if not found:
        path = UrlPath(url)
        info = path.info()
        if info is not None and info.get("type") == "directory":
            list(path.iterdir())
        found = [i for u, i in _infos.items() if u == url or u.startswith(below)]
    files = [i for i in found if i.get("type") != "directory"]
    return (
        sum(int(i.get("size") or 0) for i in files),
        max((_modified_ns(i) for i in files), default=0),
    )


def _modified_ns(info: dict[str, Any]) -> int:
    """An object's modification time in ns from what the store said (S3: ``LastModified``)."""
    value: Any = info.get("LastModified") or info.get("mtime") or info.get("last_modified")
    if hasattr(value, "timestamp"):
        return int(value.timestamp() * 1e9)
    if isinstance(value, (int, float)):
        return int(value * 1e9)
    return 0


class UrlPath:
    """An object or a prefix at ``url`` (see the module's docstring)."""

    __slots__ = ("url",)

    def __init__(self, url: str | UrlPath) -> None:
        self.url: str = url.url if isinstance(url, UrlPath) else url.rstrip("/")

    def __str__(self) -> str:
        return shown_url(self.url)

    def __repr__(self) -> str:
        return f"UrlPath({shown_url(self.url)!r})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, UrlPath) and other.url == self.url

    def __hash__(self) -> int:
        return hash(self.url)

    def __lt__(self, other: UrlPath) -> bool:
        return self.url < other.url

    def __truediv__(self, child: str) -> UrlPath:
        return UrlPath(joined(self.url, str(child)))

    @property
    def name(self) -> str:
        return name(self.url)

    @property
    def suffix(self) -> str:
        stem = self.name
        return stem[stem.rfind(".") :] if "." in stem.lstrip(".") else ""

    @property
    def stem(self) -> str:
        return self.name.removesuffix(self.suffix)

    @property
    def parent(self) -> UrlPath:
        return UrlPath(parent(self.url))

    def relative_to(self, other: UrlPath | str) -> str:
        base = other.url if isinstance(other, UrlPath) else str(other)
        if not self.url.startswith(base.rstrip("/") + "/"):
            raise ValueError(f"{self} is not under {shown_url(base)}")
        return self.url[len(base.rstrip("/")) + 1 :]

    def info(self) -> dict[str, Any] | None:
        """What the store says of the object or prefix; None when there is neither."""
        known = _infos.get(self.url)
        if known is not None:
            return known
        # An HTTP server lists no directories: a bag's prefix is known by its metadata.yaml,
        # asked for first where the name has no suffix (a bag's prefix, most likely: a URL
        # that is not there costs fsspec a HEAD and a GET).
        protocol = scheme(self.url)
        http = protocol in ("http", "https") and not self.url.endswith(".yaml")
        if http and not self.suffix and (prefix := self._bag_prefix()) is not None:
            return prefix
        s3 = protocol in ("s3", "s3a")
        if s3 and not self.suffix:
            return self._listed()
        try:
            found = self._found()
        except ObjectNotFoundError as missing:
            if isinstance(missing, BucketNotFoundError):  # nothing to list there
                return None
            if s3 and self.suffix in SUFFIX_READ:  # no such object: a prefix named so?
                return self._listed(object_missing=True)
            if protocol in ("gs", "gcs") and self.suffix in SUFFIX_READ:
                return self._prefix_info()  # gcsfs's info tells a prefix (a listing)
            return self._bag_prefix() if http and self.suffix else None
        remember(self.url, found)
        return found

    def _found(self) -> dict[str, Any]:
        """The object's info: for an MCAP or a metadata.yaml on S3, GCS or HTTP, from one read of
        its end, kept for its opening (what a HEAD would say, and the bytes read first);
        else from the store's info (a HEAD)."""
        if self.suffix in SUFFIX_READ and (found := found_by_suffix(self.url)) is not None:
            return found
        fs, path = filesystem(self.url)
        info: dict[str, Any] = call(self.url, lambda: fs.info(path))
        return info

    def _prefix_info(self) -> dict[str, Any] | None:
        """The store's info of what is not an object at this URL (a prefix), None if none."""
        fs, path = filesystem(self.url)
        try:
            info: dict[str, Any] = call(self.url, lambda: fs.info(path))
        except ObjectNotFoundError:
            return None
        remember(self.url, info)
        return info

    def _listed(self, *, object_missing: bool = False) -> dict[str, Any] | None:
        """A name without a suffix on S3 is most likely a prefix (a bag's, a fleet's): one
        listing says so and gives its objects' sizes and ETags (remembered: no HEAD for
        them); a listing of the parent finds an object of that name, unless a GET of it
        already found none (``object_missing``: the prefix's listing only)."""
        fs, path = filesystem(self.url)

        def listing() -> list[dict[str, Any]]:
            if not object_missing:
                entries: list[dict[str, Any]] = fs.ls(path, detail=True)
                return entries
            from fsspec.asyn import sync

            # s3fs's ls lists the parent too where the prefix is empty (for the object).
            entries = sync(fs.loop, fs._lsdir, path)
            if not entries:
                raise ObjectNotFoundError(f"{self}: no such object, prefix or bucket")
            return entries

        try:
            entries = call(self.url, listing)
        except ObjectNotFoundError:
            return None
        itself = [e for e in entries if e["name"].rstrip("/") == path and e["type"] != "directory"]
        if itself:
            remember(self.url, itself[0])
            return itself[0]
        for entry in entries:
            remember(joined(self.url, entry["name"].rstrip("/").rsplit("/", 1)[-1]), entry)
        found = {"type": "directory", "size": 0, "name": path}
        remember(self.url, found)
        return found

    def _bag_prefix(self) -> dict[str, Any] | None:
        """A directory's info (remembered) when this prefix holds metadata.yaml, else None."""
        if not (self / "metadata.yaml").is_file():
            return None
        found = {"type": "directory", "size": 0}
        remember(self.url, found)  # asked again by every exists()/is_dir()
        return found

    def exists(self) -> bool:
        return self.info() is not None

    def is_file(self) -> bool:
        info = self.info()
        return info is not None and info.get("type") != "directory"

    def is_dir(self) -> bool:
        info = self.info()
        return info is not None and info.get("type") == "directory"

    def stat(self) -> os.stat_result:
        info = self.info()
        if info is None:
            raise ObjectNotFoundError(f"{self}: no such object, prefix or bucket")
        return os.stat_result((0, 0, 0, 0, 0, 0, int(info.get("size") or 0), 0, 0, 0))

    def iterdir(self) -> Iterator[UrlPath]:
        """The objects and prefixes directly under this prefix."""
        fs, path = filesystem(self.url)
        entries = call(self.url, lambda: fs.ls(path, detail=True))
        for entry in entries:
            child = UrlPath(joined(self.url, entry["name"].rstrip("/").rsplit("/", 1)[-1]))
            if child != self:
                remember(child.url, entry)
                yield child

    def open(self, mode: str = "rb") -> RangeFile:
        if mode != "rb":
            raise StorageError(f"{self}: storage URLs are opened for reading only here")
        info = self.info()
        if info is None:
            raise ObjectNotFoundError(f"{self}: no such object, prefix or bucket")
        return RangeFile(self.url, info)

    def read_bytes(self) -> bytes:
        with self.open() as f:
            return f.read()

    def read_text(self, encoding: str = "utf-8", errors: str = "strict") -> str:
        return self.read_bytes().decode(encoding, errors)
