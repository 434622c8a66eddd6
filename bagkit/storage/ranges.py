"""The range requests bagkit issues itself on S3, GCS and HTTP: a span asked for with the ETag
seen at open (``If-Match``), and a suffix (``Range: bytes=-N``), whose answer gives the
object's size (``Content-Range``) and ETag with its last bytes: an object is found and its end
read in one request, where a HEAD and a range GET would be two. Azure's Blob service takes no
suffix range (only ``bytes=a-`` and ``bytes=a-b``), so its objects are found by a HEAD.
"""

from __future__ import annotations

from typing import Any

from bagkit.storage.errors import ObjectChangedError, StorageError
from bagkit.storage.filesystems import status_of
from bagkit.storage.urls import scheme, shown_url

# The schemes whose objects are opened by a suffix read (other stores: a HEAD, through fsspec).
SUFFIX_SCHEMES = ("s3", "s3a", "gs", "gcs", "http", "https")


def span(fs: Any, url: str, path: str, start: int, end: int, *, etag: str | None) -> bytes:
    """Bytes ``[start, end)``; refused by the store (412) if the object's ETag moved."""
    protocol = scheme(url)
    if etag and protocol in ("s3", "s3a"):
        return _s3_span(fs, path, start, end, etag)
    if etag and protocol in ("http", "https"):
        return bytes(fs.cat_file(path, start, end, headers={"If-Match": etag}))
    return bytes(fs.cat_file(path, start=start, end=end))


def suffix(fs: Any, url: str, path: str, length: int) -> tuple[bytes, dict[str, Any]] | None:
    """The last ``length`` bytes of the object (all of it when shorter) and what a listing
    would say of it (``size``, ``ETag``, ``type``; S3: ``LastModified``); None where no
    suffix is read (another scheme, an empty object, an HTTP server that sends the whole
    object instead).

    Raises:
        StorageError: the server sent the whole object for a range.
        ObjectChangedError: fewer bytes than its Content-Range announced.
    """
    protocol = scheme(url)
    if protocol in ("s3", "s3a"):
        answer = _s3_suffix(fs, path, length)
    elif protocol in ("gs", "gcs"):
        answer = _gcs_suffix(fs, path, length)
    elif protocol in ("http", "https"):
        answer = _http_suffix(fs, url, path, length)
    else:
        return None
    if answer is None:
        return None
    data, total, info = answer
    size = len(data) if total is None else total
    if total is None and len(data) > length:
        raise StorageError(f"{shown_url(url)}: the server does not answer range requests")
    if len(data) != min(length, size):
        raise ObjectChangedError(
            f"{shown_url(url)}: a short answer ({len(data)} bytes of the last {min(length, size)})"
        )
    info.update(type="file", size=size, name=path)
    return data, info


def _total(content_range: str | None) -> int | None:
    """The object's size from ``Content-Range: bytes a-b/size`` (None without one)."""
    if not content_range or "/" not in content_range:
        return None
    total = content_range.rsplit("/", 1)[1].strip()
    return int(total) if total.isdigit() else None


def _s3_span(fs: Any, path: str, start: int, end: int, etag: str) -> bytes:
    data, _ = _s3_get(fs, path, f"bytes={start}-{end - 1}", IfMatch=etag)
    return data


def _s3_suffix(fs: Any, path: str, length: int) -> tuple[bytes, int | None, dict[str, Any]] | None:
    try:
        data, response = _s3_get(fs, path, f"bytes=-{length}")
    except Exception as exc:
        if status_of(exc) == 416:  # an empty object has no last bytes
            return None
        raise
    info = {"ETag": response.get("ETag"), "LastModified": response.get("LastModified")}
    return data, _total(response.get("ContentRange")), info


def _s3_get(fs: Any, path: str, byte_range: str, **conditions: str) -> tuple[bytes, Any]:
    """One GetObject of ``byte_range`` through s3fs's client (its retries, credentials)."""
    from fsspec.asyn import sync

    bucket, key, _ = fs.split_path(path)

    async def get() -> tuple[bytes, Any]:
        response = await fs._call_s3(
            "get_object", Bucket=bucket, Key=key, Range=byte_range, **conditions
        )
        try:
            return bytes(await response["Body"].read()), response
        finally:
            response["Body"].close()

    return sync(fs.loop, get)


def _gcs_suffix(fs: Any, path: str, length: int) -> tuple[bytes, int | None, dict[str, Any]] | None:
    """A media GET of the JSON API with ``Range: bytes=-length`` through gcsfs's own request
    (its session, credentials and retries); its generation is what a listing gives too."""
    from fsspec.asyn import sync

    try:
        headers, data = sync(
            fs.loop, fs._call, "GET", fs.url(path), headers={"Range": f"bytes=-{length}"}
        )
    except Exception as exc:
        if status_of(exc) == 416:  # an empty object has no last bytes
            return None
        raise
    total = _total(headers.get("Content-Range"))
    if total is None and len(data) > length:
        # The whole object for a suffix (gcp-storage-emulator; Cloud Storage takes suffixes):
        # its size is asked for instead, as from an HTTP server that takes no suffix.
        return None
    info = {"ETag": headers.get("ETag"), "generation": headers.get("x-goog-generation")}
    return bytes(data), total, info


def _http_suffix(
    fs: Any, url: str, path: str, length: int
) -> tuple[bytes, int | None, dict[str, Any]] | None:
    """A GET with ``Range: bytes=-length`` through fsspec's aiohttp session (its timeouts)."""
    from fsspec.asyn import sync

    options = dict(fs.kwargs)
    headers = {**options.pop("headers", {}), "Range": f"bytes=-{length}"}

    async def get() -> tuple[bytes, int | None, dict[str, Any]] | None:
        session = await fs.set_session()
        async with session.get(fs.encode_url(path), headers=headers, **options) as response:
            if response.status == 416:
                return None
            fs._raise_not_found_for_status(response, path)
            total = _total(response.headers.get("Content-Range"))
            announced = response.headers.get("Content-Length", "")
            if total is None and announced.isdigit() and int(announced) > length:
                # The whole object for a suffix, not read (it may be GBs): a server may take
                # ranges but no suffix, so the object is asked for its size instead.
                return None
            data = await response.read()
            return data, total, {"ETag": response.headers.get("ETag")}

    return sync(fs.loop, get)
