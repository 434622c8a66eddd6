"""A read-only, seekable file over an object in storage, read by range requests.

What the bag readers need from a file: ``seek``, ``tell``, ``read``. A read is served from a
bounded cache of the ranges fetched; a miss fetches exactly what was asked (an MCAP reader
seeks by its indexes: the footer, the summary, the chunks it needs), and reading on where the
last reads ended (a file without a summary, read through) fetches ahead an eighth of what was
read on so far, up to :data:`MAX_READ_AHEAD`. A first read of an object's end (an MCAP footer)
fetches as deep into its tail as the reads of the last object of its kind went (the same
suffix, its bag beside this one's: its footer and summary), up to a quarter of the object:
one request where two would be. Every range is asked for with the ETag seen at
open (``If-Match``) where the store takes one, and its length is checked: an object that
changes while it is read is an error, never a mix of two versions.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from typing import Any

from bagkit.storage.errors import ObjectChangedError, StorageError
from bagkit.storage.filesystems import call, filesystem
from bagkit.storage.urls import scheme, shown_url

# Read-ahead: a share of the bytes read on end to end so far (at most 1/8 fetched in vain when
# the reading stops, however it reads), up to MAX_READ_AHEAD.
READ_AHEAD_SHARE = 8
MAX_READ_AHEAD = 8 << 20
# The first bytes of a file (magic, header) are fetched at once and kept for the next opening of
# the same object (the back-end is chosen by the magic, then opens the file again), for the
# last MAX_HEADS objects.
HEAD_BYTES = 1024
MAX_HEADS = 256
_HEADS: dict[tuple[str, str | None], bytes] = {}
# The ranges kept per open file; the oldest are dropped beyond.
CACHE_BYTES = 64 << 20
# How far from its end the reads of the last object of a kind went (reads contiguous with its
# end: an MCAP footer, then its summary), and the share of an object that guess may fetch. A
# kind: the suffix and the prefix two levels up (the bags of one fleet), so that another
# fleet's larger summaries are no guess here.
_TAIL_DEPTHS: dict[tuple[str, str], int] = {}
TAIL_SHARE = 4


class _Counter:
    """Bytes and requests fetched by this process (benchmarks and tests read them)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.bytes = self.requests = 0

    def add(self, size: int) -> None:
        with self.lock:
            self.bytes += size
            self.requests += 1


FETCHED = _Counter()


def fetched() -> tuple[int, int]:
    """``(bytes, requests)`` fetched by range reads in this process so far."""
    return FETCHED.bytes, FETCHED.requests


class RangeFile:
    """An object opened for reading by ranges (see the module's docstring).

    Args:
        url: the object.
        info: its size and ETag where a listing already gave them (else one HEAD request).
    """

    def __init__(self, url: str, info: dict[str, Any] | None = None) -> None:
        self.url = url
        self.name = shown_url(url)
        self._fs, self._path = filesystem(url)
        info = info or call(url, lambda: self._fs.info(self._path))
        if info.get("type") == "directory":
            raise StorageError(f"{self.name}: a prefix, not an object")
        self.size = int(info.get("size") or 0)
        self.etag = info.get("ETag") or info.get("etag")
        self.fetched_bytes = 0
        self._kind = (url.rsplit("/", 2)[0], url.rsplit("/", 1)[-1].rpartition(".")[2])
        self._tail_low = self.size  # the lowest offset read on contiguously to the end
        self._position = 0
        self._last_end = -1
        self._streak = 0
        self._cache: OrderedDict[int, bytes] = OrderedDict()
        self._cached = 0
        self.closed = False

    # The file API the readers use.
    def seekable(self) -> bool:
        return True

    def readable(self) -> bool:
        return True

    def tell(self) -> int:
        return self._position

    def seek(self, offset: int, whence: int = 0) -> int:
        base = {0: 0, 1: self._position, 2: self.size}[whence]
        self._position = max(0, base + offset)
        return self._position

    def read(self, size: int = -1) -> bytes:
        start = self._position
        end = self.size if size is None or size < 0 else min(self.size, start + size)
        if end <= start:
            return b""
        self._streak = self._streak + end - start if start == self._last_end else end - start
        data = self._cached_span(start, end)
        if data is None:
            data = self._fetch_span(start, end)
        if start < self._tail_low <= end:  # what the next object's footer read will fetch
            self._tail_low = start
            _TAIL_DEPTHS[self._kind] = self.size - start
        self._position = end
        self._last_end = end
        return data

    def readinto(self, buffer: Any) -> int:
        data = self.read(len(buffer))
        buffer[: len(data)] = data
        return len(data)

    def close(self) -> None:
        self.closed = True
        self._cache.clear()

    def __enter__(self) -> RangeFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # The cache and the fetches.
    def _cached_span(self, start: int, end: int) -> bytes | None:
        head = _HEADS.get((self.url, self.etag))
        if head is not None and end <= len(head):
            return head[start:end]
        for offset, block in reversed(self._cache.items()):
            if offset <= start and end <= offset + len(block):
                self._cache.move_to_end(offset)
                return block[start - offset : end - offset]
        return None

    def _fetch_span(self, start: int, end: int) -> bytes:
        # What a cached block (the read-ahead) holds from ``start`` on is not fetched again.
        held = next(
            (b[start - o :] for o, b in reversed(self._cache.items()) if o <= start < o + len(b)),
            b"",
        )
        first = start + len(held)
        if end == self.size and not held:  # a footer: the summary before it, as last time
            depth = min(_TAIL_DEPTHS.get(self._kind, 0), self.size // TAIL_SHARE)
            first = min(first, self.size - depth)
        ahead = min(MAX_READ_AHEAD, self._streak // READ_AHEAD_SHARE)
        if first == 0:  # the magic and the header: one request for every reader of the file
            ahead = max(ahead, HEAD_BYTES)
        fetch_end = min(self.size, max(end, first + ahead))
        block = self._fetch(first, fetch_end)
        if first == 0:
            if len(_HEADS) >= MAX_HEADS:
                _HEADS.pop(next(iter(_HEADS)))
            _HEADS[(self.url, self.etag)] = block[:HEAD_BYTES]
        if fetch_end > end or first < start or len(block) <= CACHE_BYTES // 4:
            self._keep(first, block)
        return (held + block)[: end - start] if held else block[start - first : end - first]

    def _keep(self, offset: int, block: bytes) -> None:
        self._cache[offset] = block
        self._cached += len(block)
        while self._cached > CACHE_BYTES and len(self._cache) > 1:
            _, dropped = self._cache.popitem(last=False)
            self._cached -= len(dropped)

    def _fetch(self, start: int, end: int) -> bytes:
        data = call(self.url, lambda: self._get(start, end))
        FETCHED.add(len(data))
        self.fetched_bytes += len(data)
        if len(data) != end - start:
            if len(data) == self.size and start > 0:
                raise StorageError(f"{self.name}: the server does not answer range requests")
            raise ObjectChangedError(
                f"{self.name}: the object changed while read ({len(data)} bytes at byte "
                f"{start} where {end - start} were expected)"
            )
        return data

    def _get(self, start: int, end: int) -> bytes:
        protocol = scheme(self.url)
        if self.etag and protocol in ("s3", "s3a"):
            return _s3_range(self._fs, self._path, start, end, self.etag)
        if self.etag and protocol in ("http", "https"):
            return bytes(self._fs.cat_file(self._path, start, end, headers={"If-Match": self.etag}))
        return bytes(self._fs.cat_file(self._path, start=start, end=end))


def _s3_range(fs: Any, path: str, start: int, end: int, etag: str) -> bytes:
    """A GetObject of bytes ``[start, end)`` that the store refuses (412) if the ETag moved."""
    from fsspec.asyn import sync

    bucket, key, _ = fs.split_path(path)

    async def get() -> bytes:
        response = await fs._call_s3(
            "get_object", Bucket=bucket, Key=key, Range=f"bytes={start}-{end - 1}", IfMatch=etag
        )
        try:
            return bytes(await response["Body"].read())
        finally:
            response["Body"].close()

    return sync(fs.loop, get)
