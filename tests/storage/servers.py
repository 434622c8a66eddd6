"""The stores the storage tests read from, all on 127.0.0.1: moto's S3-compatible server,
gcp-storage-emulator (GCS) and Azurite (Azure Blob Storage), each a subprocess stopped by its
pid, and a small HTTP server with byte ranges and injected faults."""

from __future__ import annotations

import hashlib
import importlib.util
import os
import shutil
import socket
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import NoReturn

import pytest

REPO = Path(__file__).resolve().parents[2]
# Installed by the Makefile (`make test`): npm's azurite, pinned there.
AZURITE = REPO / ".azurite" / "node_modules" / ".bin" / "azurite-blob"
# Azurite's well-known development account (published with Azurite: no secret), reached as
# every Azure client does, through the connection string in the environment.
AZURITE_ACCOUNT = "devstoreaccount1"
AZURITE_KEY = (
    "Eby8vdM02xNOcqFlqUwJPLlmEtlCDXJ1OUzFT50uSRZ6IFsuFq2UVErCz4I6tq/K1SZFPTOtr/KBHBeksoGMGw=="
)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class Emulator:
    """A store's server in a subprocess; ``env``: what a client needs to reach it."""

    process: subprocess.Popen[bytes]
    endpoint: str
    env: dict[str, str]

    def stop(self) -> None:
        self.process.terminate()
        try:
            self.process.wait(10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


def _serve(args: list[str], port: int) -> tuple[subprocess.Popen[bytes], str]:
    """Start ``args`` and wait until it listens on ``port`` of 127.0.0.1."""
    process = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
            return process, f"http://127.0.0.1:{port}"
        except OSError:
            if process.poll() is not None:
                break
            time.sleep(0.1)
    process.kill()
    process.wait()
    pytest.fail(f"{Path(args[0]).name} did not start")


def start_moto() -> Emulator:
    port = free_port()
    moto = str(Path(sys.executable).with_name("moto_server"))
    process, endpoint = _serve([moto, "-H", "127.0.0.1", "-p", str(port)], port)
    env = {
        "AWS_ENDPOINT_URL": endpoint,
        "AWS_ACCESS_KEY_ID": "testing",
        "AWS_SECRET_ACCESS_KEY": "testing-secret",
        "AWS_DEFAULT_REGION": "us-east-1",
    }
    return Emulator(process, endpoint, env)


def start_gcs() -> Emulator:
    """gcp-storage-emulator, in memory; clients find it by ``STORAGE_EMULATOR_HOST``.
    Skipped (failed under CI=true) where the lock's packages are not installed yet."""
    emulator = str(Path(sys.executable).with_name("gcp-storage-emulator"))
    if importlib.util.find_spec("gcsfs") is None or not Path(emulator).exists():
        needed("gcsfs or gcp-storage-emulator not installed (make .venv/.installed: the lock)")
    port = free_port()
    args = [emulator, "start", "--host", "127.0.0.1", "--port", str(port), "--in-memory", "-q"]
    process, endpoint = _serve(args, port)
    env = {
        "STORAGE_EMULATOR_HOST": endpoint,
        # Should anything ask Google's metadata server for a token, it asks a closed port here.
        "GCE_METADATA_HOST": "127.0.0.1:9",
        "GCE_METADATA_IP": "127.0.0.1:9",
    }
    return Emulator(process, endpoint, env)


def start_azurite() -> Emulator:
    """Azurite's blob service, in memory, without telemetry; clients find it by
    ``AZURE_STORAGE_CONNECTION_STRING``. Skipped (failed under CI=true) without Node.js or
    Azurite."""
    if importlib.util.find_spec("adlfs") is None:
        needed("adlfs not installed (make .venv/.installed installs the lock)")
    if shutil.which("node") is None:
        needed("Node.js not found: Azurite (the az:// tests' emulator) needs it")
    if not AZURITE.exists():
        needed(f"Azurite not installed at {AZURITE.relative_to(REPO)} (make test installs it)")
    port = free_port()
    args = [str(AZURITE), "--blobHost", "127.0.0.1", "--blobPort", str(port)]
    args += ["--inMemoryPersistence", "--disableTelemetry", "--skipApiVersionCheck", "--silent"]
    process, endpoint = _serve(args, port)
    connection = (
        f"DefaultEndpointsProtocol=http;AccountName={AZURITE_ACCOUNT};AccountKey={AZURITE_KEY};"
        f"BlobEndpoint={endpoint}/{AZURITE_ACCOUNT};"
    )
    return Emulator(process, endpoint, {"AZURE_STORAGE_CONNECTION_STRING": connection})


def needed(reason: str) -> NoReturn:
    """Skip for want of ``reason``'s tool, or under CI (``CI=true``) fail: CI never passes by
    skipping."""
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(reason)
    pytest.skip(reason)


@dataclass
class Faults:
    """What the HTTP server does to the next requests of a path."""

    fail: int = 0  # answer this many requests with ``status``
    status: int = 503
    stall_s: float = 0.0  # wait this long before answering (timeouts)
    truncate: bool = False  # send fewer bytes than announced
    change_after: int = -1  # after this many GETs, the object's ETag changes
    no_suffix: bool = False  # answer a suffix range (``bytes=-N``) with the whole object


@dataclass
class HttpStore:
    """Objects by path, served with HEAD, GET, Range and If-Match; faults per path."""

    objects: dict[str, bytes] = field(default_factory=dict)
    faults: dict[str, Faults] = field(default_factory=dict)
    gets: dict[str, int] = field(default_factory=dict)
    requests: dict[str, int] = field(default_factory=dict)  # by method: HEAD, GET
    url: str = ""
    # id(object) -> (the object, its MD5): hashed once per object, not per request (a 64 MB
    # object served by ranges, under several paths).
    digests: dict[int, tuple[bytes, str]] = field(default_factory=dict)

    def etag(self, path: str) -> str:
        faults = self.faults.get(path)
        changed = faults is not None and 0 <= faults.change_after < self.gets.get(path, 0)
        data = self.objects[path]
        known = self.digests.get(id(data))
        if known is None or known[0] is not data:
            known = self.digests[id(data)] = (data, hashlib.md5(data).hexdigest())
        digest = known[1]
        return f'"{digest}{"-2" if changed else ""}"'


class _Server(ThreadingHTTPServer):
    # socketserver listens with a backlog of 5: 16 readers connecting at once lose SYNs,
    # which their kernel sends again after a second.
    request_queue_size = 128


def start_http(store: HttpStore) -> ThreadingHTTPServer:
    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args: object) -> None:
            pass

        def _answer(self, body: bool) -> None:
            path = self.path.split("?", 1)[0]
            faults = store.faults.get(path, Faults())
            store.requests[self.command] = store.requests.get(self.command, 0) + 1
            if body:
                store.gets[path] = store.gets.get(path, 0) + 1
            if faults.stall_s:
                time.sleep(faults.stall_s)
            if faults.fail > 0:
                faults.fail -= 1
                self.send_response(faults.status)
                self.send_header("Content-Length", "0")
                self.end_headers()
                return
            data = store.objects.get(path)
            if data is None:
                self.send_response(404)
                self.send_header("Content-Length", "0")
                self.end_headers()
                return
            etag = store.etag(path)
            wanted = self.headers.get("If-Match")
            if wanted is not None and wanted != etag:
                self.send_response(412)
                self.send_header("Content-Length", "0")
                self.end_headers()
                return
            start, end, status = 0, len(data), 200
            ranged = self.headers.get("Range")
            if ranged and not (faults.no_suffix and ranged.startswith("bytes=-")):
                first, _, last = ranged.removeprefix("bytes=").partition("-")
                if first:  # bytes=A-B, or bytes=A- (to the end)
                    start = int(first)
                    end = min(len(data), int(last) + 1) if last else len(data)
                else:  # a suffix: the last bytes, all of them when the object is shorter
                    start = max(0, len(data) - int(last))
                status = 206
            part = memoryview(data)[start:end]  # no copy (a HEAD of a 256 MB object)
            self.send_response(status)
            self.send_header("Content-Length", str(len(part)))
            self.send_header("ETag", etag)
            self.send_header("Accept-Ranges", "bytes")
            if status == 206:
                self.send_header("Content-Range", f"bytes {start}-{end - 1}/{len(data)}")
            self.end_headers()
            if body:
                self.wfile.write(part[: len(part) // 2] if faults.truncate else part)

        def do_HEAD(self) -> None:
            self._answer(body=False)

        def do_GET(self) -> None:
            self._answer(body=True)

    server = _Server(("127.0.0.1", free_port()), Handler)
    server.daemon_threads = True
    threading.Thread(target=server.serve_forever, daemon=True).start()
    store.url = f"http://127.0.0.1:{server.server_address[1]}"
    return server


def real_bucket() -> str | None:
    """``BAGKIT_TEST_BUCKET`` (``s3://bucket/prefix``, ``gs://...``): the same tests against a
    real store with the credentials of the environment."""
    return os.environ.get("BAGKIT_TEST_BUCKET") or None
