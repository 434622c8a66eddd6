"""A read-only, seekable file over an object in storage, read by range requests.

What the bag readers need from a file: ``seek``, ``tell``, ``read``. A read is served from a
bounded cache of the ranges fetched; a miss fetches exactly what was asked (an MCAP reader
seeks by its indexes: the footer, the summary, the chunks it needs), and reading on where the
last reads ended (a file without a summary, read through) fetches ahead an eighth of what was
read on so far, up to :data:`MAX_READ_AHEAD`. A first read of an object's end (an MCAP's
closing magic, its footer) fetches as deep into its tail as the reads of the last object of
its kind went, and an eighth more (the same suffix, its bag beside this one's: its footer and
summary), :data:`FIRST_TAIL_BYTES` before any, up to a quarter of the object: one request
where two would be. An object named by its URL on S3, GCS or HTTP is found by such a read of its
end (:func:`found_by_suffix`: a suffix range gives its size and ETag too, no HEAD). The blocks
fetched at an object's ends are kept for its next opening (the back-end is chosen by them,
then opens the file again). Every range is asked for with the ETag seen at open
(``If-Match``) where the store takes one, and its length is checked: an object that changes
while it is read is an error, never a mix of two versions.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from typing import Any

from bagkit.storage import ranges
from bagkit.storage.errors import ObjectChangedError, StorageError
from bagkit.storage.filesystems import call, filesystem
from bagkit.storage.urls import scheme, shown_url

# Read-ahead: a share of the bytes read on end to end so far (at most 1/8 fetched in vain when
# the reading stops, however it reads), up to MAX_READ_AHEAD.
READ_AHEAD_SHARE = 8
MAX_READ_AHEAD = 8 << 20
# A file's first request fetches at least this much (magic and header: what a back-end is
# chosen by when its end is no MCAP's).
HEAD_BYTES = 1024
# The ranges kept per open file; the oldest are dropped beyond.
CACHE_BYTES = 64 << 20
# How far from its end the reads of the last object of a kind went (reads contiguous with its
# end: an MCAP footer, then its summary), and the share of an object that guess may fetch. A
# kind: the suffix and the prefix two levels up (the bags of one fleet), so that another
# fleet's larger summaries are no guess here. Reads of the last bytes only (a closing magic, a
# footer: MIN_LEARNED_DEPTH) say nothing of a summary's depth and are not learned: a bag read
# beside this one would otherwise guess from them.
_TAIL_DEPTHS: dict[tuple[str, str], int] = {}
TAIL_SHARE = 4
TAIL_SLACK = 8
MIN_LEARNED_DEPTH = 64
# A read ending this close below the tail read so far still extends it: rosbag2's Metadata
# record (read for a bag without metadata.yaml) ends where a DataEnd record (13 bytes) starts,
# right before the summary.
TAIL_GAP = 64
# The first guess, before any object of the kind was read: small bags' summaries (schemas,
# channels, a few chunk indexes) are a few to a few tens of KiB; a deeper one costs a second
# request on its kind's first object only.
FIRST_TAIL_BYTES = 16 << 10


# An object as its openings see it: URL, ETag, size (without an ETag, a size that changed).
_Key = tuple[str, str | None, int]


class _Kept:
    """The blocks fetched at the ends of the last MAX_OBJECTS objects (by URL, ETag, size), at
    most MAX_BYTES: what the next opening of the same object reads first."""

    MAX_OBJECTS = 256
    MAX_BYTES = 32 << 20

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.blocks: OrderedDict[_Key, list[tuple[int, bytes]]] = OrderedDict()
        self.bytes = 0

    def get(self, key: _Key) -> list[tuple[int, bytes]]:
        with self.lock:
            return list(self.blocks.get(key, ()))

    def add(self, key: _Key, offset: int, block: bytes) -> None:
        if len(block) > self.MAX_BYTES // 4:
            return
        with self.lock:
            self.blocks.setdefault(key, []).append((offset, block))
            self.blocks.move_to_end(key)
            self.bytes += len(block)
            while self.bytes > self.MAX_BYTES or len(self.blocks) > self.MAX_OBJECTS:
                _, dropped = self.blocks.popitem(last=False)
                self.bytes -= sum(len(b) for _, b in dropped)


_KEPT = _Kept()


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
        info: its size and ETag where a listing or :func:`found_by_suffix` gave them (else
            one HEAD request).
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
        self._key: _Key = (url, self.etag, self.size)
        self._kind = _kind_of(url)
        self._tail_low = self.size  # the lowest offset read on contiguously to the end
        self._position = 0
        self._last_end = -1
        self._streak = 0
        self._cache: OrderedDict[int, bytes] = OrderedDict()
        self._cached = 0
        for offset, block in _KEPT.get(self._key):
            self._keep(offset, block)
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
        if start < self._tail_low <= end + TAIL_GAP:  # what the next object's first read fetches
            self._tail_low = start
            if self.size - start >= MIN_LEARNED_DEPTH:
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
        for offset, block in reversed(self._cache.items()):
            if offset <= start and end <= offset + len(block):
                self._cache.move_to_end(offset)
                return block[start - offset : end - offset]
        return None

    def _fetch_span(self, start: int, end: int) -> bytes:
        # What a cached block (the read-ahead) holds from ``start`` on is not fetched again,
        # nor what one (the tail fetched with a footer) holds up to ``end``.
        blocks = list(reversed(self._cache.items()))
        held = next((b[start - o :] for o, b in blocks if o <= start < o + len(b)), b"")
        first = start + len(held)
        later = next(((o, b) for o, b in blocks if first < o < end <= o + len(b)), None)
        if later is not None:
            block = self._fetch(first, later[0])
            if len(block) <= CACHE_BYTES // 4:
                self._keep(first, block)
            return held + block + later[1][: end - later[0]]
        if end == self.size and not held:  # a footer: the summary before it, as last time
            first = min(first, self.size - self._tail_guess())
        ahead = min(MAX_READ_AHEAD, self._streak // READ_AHEAD_SHARE)
        if first == 0:  # the magic and the header: one request for every reader of the file
            ahead = max(ahead, HEAD_BYTES)
        fetch_end = min(self.size, max(end, first + ahead))
        block = self._fetch(first, fetch_end)
        if first == 0:
            _KEPT.add(self._key, 0, block[:HEAD_BYTES])
        elif fetch_end == self.size:
            _KEPT.add(self._key, first, block)
        if fetch_end > end or first < start or len(block) <= CACHE_BYTES // 4:
            self._keep(first, block)
        return (held + block)[: end - start] if held else block[start - first : end - first]

    def _tail_guess(self) -> int:
        """How much of the object's end its first read of the end fetches."""
        depth = _TAIL_DEPTHS.get(self._kind)
        guess = FIRST_TAIL_BYTES if depth is None else depth + depth // TAIL_SLACK
        return min(guess, self.size // TAIL_SHARE)

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
        return ranges.span(self._fs, self.url, self._path, start, end, etag=self.etag)


def _kind_of(url: str) -> tuple[str, str]:
    """The objects whose tails are alike: the prefix two levels up (the bags of one fleet)
    and the suffix."""
    return url.rsplit("/", 2)[0], url.rsplit("/", 1)[-1].rpartition(".")[2]


def found_by_suffix(url: str) -> dict[str, Any] | None:
    """What a listing would say of the object at ``url`` (size, ETag), from one suffix read
    as deep as its kind's tails go (:data:`FIRST_TAIL_BYTES` before any); the bytes are kept
    for its opening, which then reads its end without a request. None where the store is not
    read so (``ranges.SUFFIX_SCHEMES``), the object is empty or the server sends all of it
    for a suffix: ask for its info instead.

    Raises:
        ObjectNotFoundError: no such object (nor bucket); other StorageErrors as any request.
    """
    if scheme(url) not in ranges.SUFFIX_SCHEMES:
        return None
    fs, path = filesystem(url)
    depth = _TAIL_DEPTHS.get(_kind_of(url))
    guess = FIRST_TAIL_BYTES if depth is None else depth + depth // TAIL_SLACK
    answer = call(url, lambda: ranges.suffix(fs, url, path, min(guess, _Kept.MAX_BYTES // 4)))
    if answer is None:
        return None
    data, info = answer
    FETCHED.add(len(data))
    _KEPT.add((url, info.get("ETag"), info["size"]), info["size"] - len(data), data)
    return info
