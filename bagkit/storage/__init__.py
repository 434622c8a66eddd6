"""Bags where fleets keep them: object storage and HTTP servers, read by range.

``s3://``, ``gs://``, ``az://``, ``http(s)://`` and other fsspec URLs name a bag (a prefix
holding ``metadata.yaml`` and its files, or a single storage file) or a prefix of bags. The
bag layer opens them through :class:`~bagkit.storage.paths.UrlPath` and
:class:`~bagkit.storage.range_file.RangeFile`; nothing above it needs to know where a bag is.
fsspec and its filesystems are imported only when a URL is opened.
"""

from __future__ import annotations

from bagkit.storage.errors import StorageError
from bagkit.storage.urls import is_url, shown_url

__all__ = ["StorageError", "is_url", "shown_url"]
