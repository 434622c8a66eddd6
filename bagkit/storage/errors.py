"""Errors of the storage layer: a URL that cannot be read (exit code 2, like a bad bag path).

Every message names the URL as :func:`bagkit.storage.urls.shown_url` shows it: never a
password, a token or a signed query.
"""

from __future__ import annotations

from bagkit.errors import BagkitError, OptionError


class StorageError(BagkitError):
    """An object or prefix in storage that cannot be read or written."""


class OutputExistsError(StorageError, OptionError):
    """Something is already at the output URL and replacing it was not asked
    (``output.force``)."""


class UnsupportedUrlError(StorageError):
    """A URL whose scheme no installed filesystem serves (or that needs an extra installed)."""


class ObjectNotFoundError(StorageError):
    """No such object, prefix or bucket."""


class BucketNotFoundError(ObjectNotFoundError):
    """No such bucket (S3 says so: nothing under it needs listing)."""


class AccessDeniedError(StorageError):
    """No credentials found, or the store refused them (403)."""


class ObjectChangedError(StorageError):
    """The object changed (ETag or size) or was cut short while it was read."""


class UnreachableError(StorageError):
    """Timeouts or server errors (5xx) that outlasted the retries."""
