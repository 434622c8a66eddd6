"""A ``gs://`` object named by its URL is found by one suffix read (its size and ETag with its
end), no metadata request: a unit test of that core with gcsfs faked at the request it sends
(``_call``), since gcp-storage-emulator, the tests' GCS server, answers a suffix range with
the whole object (Cloud Storage takes suffixes). The tests against the emulator cover the
fallback (the size asked for instead)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from bagkit.bag import bag_info
from bagkit.storage import filesystems
from bagkit.storage.range_file import FIRST_TAIL_BYTES, fetched, found_by_suffix

GOLDEN = Path(__file__).resolve().parents[2] / "fixtures" / "nominal" / "golden"


class StatusError(Exception):
    """What gcsfs raises for an error status (an ``HttpError`` carries ``code``)."""

    def __init__(self, code: int) -> None:
        super().__init__(f"HTTP {code}")
        self.code = code


class FakeGcs:
    """gcsfs's public surface that bagkit uses, over one object held in memory; a store that
    takes suffix ranges (``suffixes``) or sends the whole object for one (the emulator)."""

    def __init__(self, blob: bytes, *, suffixes: bool = True) -> None:
        from fsspec.asyn import get_loop

        self.loop = get_loop()
        self.blob = blob
        self.suffixes = suffixes
        self.sent: list[tuple[str, str]] = []

    def _strip_protocol(self, url: str) -> str:
        return url.removeprefix("gs://")

    def url(self, path: str) -> str:
        return f"https://storage.test/{path}?alt=media"

    async def _call(self, method: str, url: str, headers: dict[str, str]) -> Any:
        self.sent.append((method, headers.get("Range", "")))
        if not self.blob:
            raise StatusError(416)
        if not self.suffixes:
            return {"ETag": "e1"}, self.blob
        tail = self.blob[-int(headers["Range"].removeprefix("bytes=-")) :]
        start = len(self.blob) - len(tail)
        answer = {
            "Content-Range": f"bytes {start}-{len(self.blob) - 1}/{len(self.blob)}",
            "ETag": "e1",
            "x-goog-generation": "7",
        }
        return answer, tail

    def cat_file(self, path: str, start: int, end: int) -> bytes:
        self.sent.append(("GET", f"bytes={start}-{end - 1}"))
        return self.blob[start:end]

    def info(self, path: str) -> dict[str, Any]:
        self.sent.append(("INFO", ""))
        return {"type": "file", "size": len(self.blob), "name": path, "etag": "e1"}


def serving(monkeypatch: pytest.MonkeyPatch, fake: FakeGcs) -> FakeGcs:
    monkeypatch.setitem(filesystems._filesystems, "gs", fake)  # type: ignore[arg-type]
    return fake


def test_an_object_is_found_by_its_end(monkeypatch: pytest.MonkeyPatch) -> None:
    """One GET of the end, no metadata request; the size is the object's, not the tail's."""
    blob = bytes(range(256)) * 200
    fake = serving(monkeypatch, FakeGcs(blob))
    info = found_by_suffix("gs://b/kind1/x/a.mcap")
    assert info is not None
    assert (info["size"], info["ETag"], info["generation"]) == (len(blob), "e1", "7")
    assert fake.sent == [("GET", f"bytes=-{FIRST_TAIL_BYTES}")]


def test_info_of_a_bare_mcap_sends_no_metadata_request(monkeypatch: pytest.MonkeyPatch) -> None:
    """``info`` of a bare ``.mcap`` named by its gs:// URL: GETs only, the first a suffix,
    and it reports what the file on disk holds."""
    mcap = next(GOLDEN.glob("*.mcap"))
    fake = serving(monkeypatch, FakeGcs(mcap.read_bytes()))
    before = fetched()
    remote = bag_info("gs://b/kind2/x/bare.mcap")
    assert remote.message_count == bag_info(mcap).message_count > 0
    assert [method for method, _ in fake.sent] == ["GET"] * len(fake.sent)
    assert fake.sent[0][1].startswith("bytes=-")
    assert fetched()[1] - before[1] == len(fake.sent)


@pytest.mark.parametrize(
    ("blob", "suffixes"), [(b"", True), (b"x" * (FIRST_TAIL_BYTES + 1), False)]
)
def test_no_suffix_answer_asks_for_the_size(
    monkeypatch: pytest.MonkeyPatch, blob: bytes, suffixes: bool
) -> None:
    """An empty object (416) and a store that sends the whole object for a suffix: no info
    from the suffix read (the caller asks the store's info instead)."""
    serving(monkeypatch, FakeGcs(blob, suffixes=suffixes))
    assert found_by_suffix("gs://b/kind3/x/a.mcap") is None
