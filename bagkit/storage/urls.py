"""Which inputs are URLs, and how a URL is shown (never with its secrets)."""

from __future__ import annotations

import re
from urllib.parse import urlsplit, urlunsplit

# ``scheme://``: two letters at least, so that a Windows drive (``C:\``) is never one; ``file``
# URLs are local paths and stay so.
_URL = re.compile(r"^([a-zA-Z][a-zA-Z0-9+.-]+)://")
LOCAL_SCHEMES = ("file",)
# What fsspec names the schemes that bagkit documents (others are passed to fsspec as given).
CLOUD_SCHEMES = ("s3", "s3a", "gs", "gcs", "az", "abfs", "abfss", "http", "https")


def is_url(text: object) -> bool:
    """True for ``scheme://...`` other than ``file://`` (a string, or a UrlPath): a bag in
    storage, not on this disk."""
    text = getattr(text, "url", text)
    if not isinstance(text, str):
        return False
    match = _URL.match(text)
    return match is not None and match.group(1).lower() not in LOCAL_SCHEMES


def location(path: object) -> str:
    """A bag's path as text that opens it again: a URL in full (a presigned URL keeps its
    signed query; a :class:`~bagkit.storage.paths.UrlPath` gives its ``.url``), anything
    else as ``str``. What fleet tasks are given; never shown (:func:`shown_url` is)."""
    url = getattr(path, "url", None)
    return url if isinstance(url, str) else str(path)


def shown_as(path: str) -> str:
    """``path`` as messages and reports name it: a URL by :func:`shown_url`, else as is."""
    return shown_url(path) if is_url(path) else path


def path_part(url: str) -> str:
    """The URL without its query and fragment (what its name and suffix are read from)."""
    return url.split("?", 1)[0].split("#", 1)[0]


def scheme(url: str) -> str:
    """The URL's scheme, lower case (``s3``, ``https``)."""
    return url.split("://", 1)[0].lower()


def shown_url(url: str) -> str:
    """``url`` without what may be a secret: the user and password, and the query (presigned
    URLs carry their signature there, Azure its SAS token), replaced by ``?...``. Azure's
    ``abfs://container@account.dfs.core.windows.net/`` keeps its container (no password)."""
    try:
        parts = urlsplit(url)
    except ValueError:
        return url.split("://", 1)[0] + "://..."
    user, at, host = parts.netloc.rpartition("@")
    container = at and ":" not in user and parts.scheme.lower() in ("abfs", "abfss", "az")
    netloc = parts.netloc if container else host
    query = "..." if parts.query else ""
    return urlunsplit((parts.scheme, netloc, parts.path, query, ""))


def joined(url: str, name: str) -> str:
    """``url/name`` (one slash between)."""
    return url.rstrip("/") + "/" + name.lstrip("/")


def parent(url: str) -> str:
    """The prefix holding ``url`` (never above ``scheme://host``)."""
    head, _, path = url.rstrip("/").partition("://")
    if "/" not in path:
        return url
    return f"{head}://{path.rsplit('/', 1)[0]}"


def name(url: str) -> str:
    """The last segment of the URL's path, without query."""
    return path_part(url).rstrip("/").rsplit("/", 1)[-1]
