"""The fsspec filesystem behind a URL, and every call to it: retried, its errors translated.

Credentials and endpoints come from where each client library looks by itself (the
environment, profiles, instance roles; an S3-compatible endpoint from ``AWS_ENDPOINT_URL``),
never from bagkit's command line. Filesystems are made once per process and scheme (fsspec
caches them too), so a Dask worker that reads many bags opens its connections once.
"""

from __future__ import annotations

import errno
import importlib
import os
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

from bagkit.storage.errors import (
    AccessDeniedError,
    BucketNotFoundError,
    ObjectChangedError,
    ObjectNotFoundError,
    StorageError,
    UnreachableError,
    UnsupportedUrlError,
)
from bagkit.storage.urls import scheme, shown_url

if TYPE_CHECKING:
    from fsspec import AbstractFileSystem

T = TypeVar("T")

# Seconds: a request that hears nothing this long is a timeout (then retried).
TIMEOUT_S = float(os.environ.get("BAGKIT_STORAGE_TIMEOUT", "30"))
# Attempts per request on a timeout, a lost connection or a 5xx, waiting BACKOFF_S * 2**i
# between them.
ATTEMPTS = int(os.environ.get("BAGKIT_STORAGE_ATTEMPTS", "4"))
BACKOFF_S = float(os.environ.get("BAGKIT_STORAGE_BACKOFF", "0.25"))
# Which package and extra of pyproject.toml serve a scheme, for the error that says what to
# install: one extra per client library (an S3 user gets neither grpc nor the Azure SDK).
_PACKAGES: dict[str, tuple[str, str]] = {
    **dict.fromkeys(("s3", "s3a"), ("s3fs", "storage")),
    **dict.fromkeys(("http", "https"), ("aiohttp", "storage")),
    **dict.fromkeys(("gs", "gcs"), ("gcsfs", "gcs")),
    **dict.fromkeys(("az", "abfs", "abfss"), ("adlfs", "azure")),
}
# gcsfs's default class (``gcsfs.GCSFileSystem`` in recent releases) first asks a gRPC control
# API for each bucket's layout, and asks again after every failure (an emulator, an anonymous
# reader): a minute per call where it cannot. Its JSON-API base class reads every bucket but
# zonal ones.
_CLASSES = {"gs": ("gcsfs.core", "GCSFileSystem"), "gcs": ("gcsfs.core", "GCSFileSystem")}

_filesystems: dict[str, AbstractFileSystem] = {}


def filesystem(url: str) -> tuple[AbstractFileSystem, str]:
    """The filesystem serving ``url`` and the path it names there.

    Raises:
        UnsupportedUrlError: no filesystem for the scheme, or its package is not installed.
    """
    protocol = scheme(url)
    try:
        import fsspec
    except ImportError:
        raise UnsupportedUrlError(
            f"{shown_url(url)}: reading URLs needs fsspec: pip install 'bagkit[storage]'"
        ) from None
    fs = _filesystems.get(protocol)
    if fs is None:
        try:
            cls = _filesystem_class(fsspec, protocol)
        except ValueError:
            raise UnsupportedUrlError(
                f"{shown_url(url)}: unknown URL scheme {protocol!r} "
                "(s3://, gs://, az://, http(s):// or another fsspec protocol)"
            ) from None
        except ImportError:
            raise UnsupportedUrlError(f"{shown_url(url)}: {_missing(protocol)}") from None
        fs = cls(**_options(protocol))
        _filesystems[protocol] = fs
    return fs, fs._strip_protocol(url)


def _filesystem_class(fsspec: Any, protocol: str) -> type[AbstractFileSystem]:
    """fsspec's class for ``protocol``, or the one bagkit chooses instead (``_CLASSES``)."""
    if protocol in _CLASSES:
        module, name = _CLASSES[protocol]
        cls: type[AbstractFileSystem] = getattr(importlib.import_module(module), name)
        return cls
    return fsspec.get_filesystem_class(protocol)


def _missing(protocol: str) -> str:
    """What to install to read ``protocol://`` URLs."""
    if protocol in _PACKAGES:
        package, extra = _PACKAGES[protocol]
        return f"reading {protocol}:// URLs needs {package}: pip install 'bagkit[{extra}]'"
    return f"reading {protocol}:// URLs needs the fsspec implementation of {protocol}"


def _options(protocol: str) -> dict[str, Any]:
    """Timeouts and retries per client; no credentials (each library finds them), except that
    a GCS emulator (``STORAGE_EMULATOR_HOST``) is read anonymously."""
    if protocol in ("s3", "s3a"):
        return {
            "config_kwargs": {
                "connect_timeout": TIMEOUT_S,
                "read_timeout": TIMEOUT_S,
                "retries": {"max_attempts": ATTEMPTS, "mode": "standard"},
            },
        }
    if protocol in ("http", "https"):
        import aiohttp

        return {"client_kwargs": {"timeout": aiohttp.ClientTimeout(sock_read=TIMEOUT_S)}}
    if protocol in ("gs", "gcs"):
        options: dict[str, Any] = {"requests_timeout": TIMEOUT_S}
        # An emulator takes no credentials: anonymous, as Google's own client library does
        # there (and no look-up of the machine's metadata server for a token).
        if os.environ.get("STORAGE_EMULATOR_HOST"):
            options["token"] = "anon"
        return options
    if protocol in ("az", "abfs", "abfss"):
        return {"connection_timeout": int(TIMEOUT_S), "read_timeout": int(TIMEOUT_S)}
    return {}


def call(url: str, what: Callable[[], T], *, retries: bool = True) -> T:
    """``what()``, retried with backoff on timeouts, lost connections and 5xx answers; any
    failure raised as one :class:`StorageError` naming ``url`` (shown without secrets)."""
    attempts = ATTEMPTS if retries else 1
    for attempt in range(attempts):
        try:
            return what()
        except StorageError:
            raise
        except Exception as exc:
            error = translated(url, exc)
            if not isinstance(error, UnreachableError) or attempt == attempts - 1:
                raise error from None
        time.sleep(BACKOFF_S * 2**attempt)
    raise AssertionError("unreachable")


def status_of(exc: BaseException) -> int | None:
    """The HTTP status behind an exception of aiohttp, botocore, s3fs, gcsfs (``code``) or
    the Azure SDK (``status_code``), if any."""
    for error in (exc, exc.__cause__, exc.__context__):
        if error is None:
            continue
        for attribute in ("status", "status_code", "code"):
            status = getattr(error, attribute, None)
            if isinstance(status, int) and 100 <= status < 600:
                return status
        response = getattr(error, "response", None)
        if isinstance(response, dict):
            code = response.get("ResponseMetadata", {}).get("HTTPStatusCode")
            if isinstance(code, int):
                return code
    return None


def _error_code(exc: BaseException) -> str | None:
    """S3's error code behind an exception of botocore or s3fs (``NoSuchBucket``), if any."""
    for error in (exc, exc.__cause__, exc.__context__):
        response = getattr(error, "response", None)
        if isinstance(response, dict):
            code = response.get("Error", {}).get("Code")
            if isinstance(code, str):
                return code
    return None


def _kind(exc: BaseException) -> str:
    names = {type(e).__name__ for e in (exc, exc.__cause__, exc.__context__) if e is not None}
    return " ".join(sorted(names))


def translated(url: str, exc: BaseException) -> StorageError:
    """One :class:`StorageError` for what a client library raised, naming ``url`` safely."""
    shown = shown_url(url)
    status = status_of(exc)
    kind = _kind(exc)
    if status == 412 or "PreconditionFailed" in str(exc):
        return ObjectChangedError(f"{shown}: the object changed while read (its ETag moved)")
    if status == 416:
        return ObjectChangedError(f"{shown}: the object is shorter than when it was opened")
    if "NoCredentials" in kind or "Unable to locate credentials" in str(exc):
        return AccessDeniedError(
            f"{shown}: no credentials found (environment, profile or instance role)"
        )
    # fsspec's HTTP filesystem raises FileNotFoundError for any failed HEAD and GET: the status
    # behind it decides.
    if status in (401, 403) or (status is None and isinstance(exc, PermissionError)):
        return AccessDeniedError(f"{shown}: access denied ({status or 403})")
    if _error_code(exc) == "NoSuchBucket":
        return BucketNotFoundError(f"{shown}: no such bucket")
    if status == 404 or (status is None and isinstance(exc, FileNotFoundError)):
        return ObjectNotFoundError(f"{shown}: no such object, prefix or bucket")
    if (status is not None and (status >= 500 or status == 429)) or _transient(exc, kind):
        return UnreachableError(
            f"{shown}: the store did not answer after {ATTEMPTS} attempts ({_reason(exc, status)})"
        )
    return StorageError(f"{shown}: {_reason(exc, status)}")


def _transient(exc: BaseException, kind: str) -> bool:
    if isinstance(exc, (TimeoutError, ConnectionError)):
        return True
    if any(word in kind for word in ("Timeout", "Connection", "Disconnected", "Payload")):
        return True
    return isinstance(exc, OSError) and exc.errno in (errno.ETIMEDOUT, errno.ECONNRESET)


def _reason(exc: BaseException, status: int | None) -> str:
    if status is not None:
        return f"HTTP {status}"
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return text if "://" not in text else type(exc).__name__  # never echo a URL back
