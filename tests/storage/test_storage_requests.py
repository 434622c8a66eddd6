"""How few requests a bag in storage costs: ``info`` of an MCAP fetches its closing magic,
footer and summary in one request (its header only when the summary is not enough), and
files that are cut or not ROS 2 still read as they do on disk."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest
from mcap.writer import Writer

from bagkit.bag import BagError, bag_info
from bagkit.storage.range_file import FIRST_TAIL_BYTES, TAIL_SHARE, TAIL_SLACK, fetched
from tests.storage.conftest import Store
from tests.storage.servers import Faults, HttpStore
from tests.storage.test_storage_read import summary_bytes


def counted_info(url: str) -> tuple[int, int]:
    """(bytes, range requests) of ``bag_info(url)``."""
    before = fetched()
    bag_info(url)
    after = fetched()
    return after[0] - before[0], after[1] - before[1]


def test_info_of_an_mcap_is_one_request(store: Store, local_bags: Path, tmp_path: Path) -> None:
    """The tail guess holds the summary: magic, header and footer are not fetched apart; a
    second bag of the same fleet is guessed from the first (a summary deeper than the first
    guess)."""
    file = local_bags / "fleet" / "a" / "a_0.mcap"
    store.put(file, "single/a/a.mcap")
    spent, requests = counted_info(f"{store.base}/single/a/a.mcap")
    assert requests == 1
    assert summary_bytes(file) <= spent <= 2 * summary_bytes(file)
    # A bag prefix: its metadata.yaml and one request per file, once the kind is known.
    golden = Path(__file__).resolve().parents[2] / "fixtures" / "nominal" / "golden"
    for name in ("g1", "g2"):
        store.put(golden, f"deep/{name}")
    counted_info(f"{store.base}/deep/g1")  # the first of its kind: a summary deeper than 16 KiB
    spent, requests = counted_info(f"{store.base}/deep/g2")
    assert requests == 2
    mcap = next(golden.glob("*.mcap"))
    assert spent <= 1.25 * summary_bytes(mcap) + (golden / "metadata.yaml").stat().st_size


def test_a_cut_bag_is_salvaged_as_on_disk(store: Store, local_bags: Path, tmp_path: Path) -> None:
    """No closing magic: the header is read and the file scanned, as on disk."""
    data = (local_bags / "fleet" / "a" / "a_0.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 3 // 5])
    store.put(cut, "cut/c/cut.mcap")
    remote, local = bag_info(f"{store.base}/cut/c/cut.mcap"), bag_info(cut)
    assert not remote.summary and remote.problems and len(remote.problems) == len(local.problems)
    assert remote.message_count == local.message_count > 0
    assert [t.count for t in remote.topics] == [t.count for t in local.topics]
    assert (remote.start_ns, remote.end_ns) == (local.start_ns, local.end_ns)


def test_an_mcap_of_another_profile_is_refused_as_on_disk(store: Store, tmp_path: Path) -> None:
    """Channels that are not CDR: the header is read for its profile, and the same error."""
    file = tmp_path / "ros1.mcap"
    with open(file, "wb") as f:
        writer = Writer(f)
        writer.start(profile="ros1", library="test")
        schema = writer.register_schema("std_msgs/String", "ros1msg", b"string data")
        channel = writer.register_channel("/chatter", "ros1", schema)
        for i in range(3):
            writer.add_message(channel, i, b"\x02\x00\x00\x00hi", i)
        writer.finish()
    store.put(file, "foreign/f/ros1.mcap")
    with pytest.raises(BagError) as on_disk:
        bag_info(file)
    with pytest.raises(BagError) as remote:
        bag_info(f"{store.base}/foreign/f/ros1.mcap")
    assert "MCAP profile 'ros1' is not ROS 2" in str(on_disk.value)
    assert str(remote.value).split(": ", 1)[1] == str(on_disk.value).split(": ", 1)[1]


def test_bags_of_a_prefix_read_at_once_fail_one_by_one(
    moto_store: Store, local_bags: Path, tmp_path: Path
) -> None:
    """info and catalog read a prefix's bags several at a time; a bag that cannot be read is
    one bag's problem, named by its URL, among the others read."""
    from bagkit.fleet.catalog import complete_update, plan_update
    from bagkit.fleet.listing import folder_info

    for bag in ("a", "b"):
        moto_store.put(local_bags / "fleet" / bag, f"mixed/{bag}")
    (tmp_path / "notes.mcap").write_bytes(b"not a bag at all, " * 100)
    moto_store.put(tmp_path / "notes.mcap", "mixed/notes.mcap")
    base = f"{moto_store.base}/mixed"
    folder = folder_info(base)
    assert folder is not None
    assert [b.path for b in folder.bags] == [f"{base}/a", f"{base}/b"]
    assert list(folder.unread) == [f"{base}/notes.mcap"]
    assert folder.unread[f"{base}/notes.mcap"].startswith(f"{base}/notes.mcap: ")
    frame = complete_update(plan_update([base], tmp_path / "c.parquet"), None)
    problems = frame.drop_duplicates("path").set_index("path")["problems"]
    assert problems[f"{base}/notes.mcap"].startswith(f"{base}/notes.mcap: ")
    assert problems[f"{base}/a"] == problems[f"{base}/b"] == ""
    counts = frame[frame.topic == "/gps/fix"].set_index("path")["count"]
    assert counts.to_dict() == {f"{base}/a": 3, f"{base}/b": 5}


def test_filter_around_writes_its_cuts_under_an_output_url(
    moto_store: Store, local_bags: Path
) -> None:
    """One bag per episode, under the URL (uploaded), named by their URLs in what is printed;
    the same messages as the cuts written on disk."""
    import json

    from tests.storage.test_storage_read import cli

    moto_store.put(local_bags / "fleet" / "b", "around/b")
    base = moto_store.base
    args = ["--around", "/gps/fix: latitude > 48.0000015", "--before", "1", "--after", "1"]
    args += ["--format", "json"]
    remote = cli(["filter", f"{base}/around/b", "-o", f"{base}/cuts", *args], moto_store.env)
    assert remote.returncode == 0, remote.stderr
    local_out = local_bags / "around-cuts"
    local = cli(["filter", str(local_bags / "fleet" / "b"), "-o", str(local_out), *args], {})
    assert local.returncode == 0, local.stderr
    cuts, expected = json.loads(remote.stdout), json.loads(local.stdout)
    assert len(cuts) == len(expected) >= 1
    for cut, on_disk in zip(cuts, expected, strict=True):
        name = Path(on_disk["output"]).name
        assert cut["output"] == f"{base}/cuts/{name}"
        assert cut["message_count"] == on_disk["message_count"] > 0
        info = cli(["info", cut["output"], "--format", "json"], moto_store.env)
        assert json.loads(info.stdout)["message_count"] == on_disk["message_count"]
    again = cli(["filter", f"{base}/around/b", "-o", f"{base}/cuts", *args], moto_store.env)
    assert again.returncode == 2 and "exists (use --force to replace it)" in again.stderr
    assert again.stderr.count("\n") == 1 and again.stderr.startswith("error: ")


def tail_depths(file: Path) -> tuple[int, int]:
    """How far from its end ``info`` must read an MCAP: to its summary's start (a bag with
    metadata.yaml), and to its ``rosbag2`` Metadata record's start (a bare file, whose
    compression mode that record says), from the summary as the ``mcap`` package reads it."""
    from mcap.reader import make_reader

    size = file.stat().st_size
    with open(file, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    record = min(m.offset for m in summary.metadata_indexes if m.name == "rosbag2")
    return summary_bytes(file), size - record


def first_then_learned(depth: int, cap: int | None = None) -> tuple[int, int]:
    """Requests for a tail of ``depth`` bytes: of the first object of its kind (read
    FIRST_TAIL_BYTES deep, up to ``cap``: one request when that holds it, else one more) and
    of the next (read as deep as the first went and an eighth more). A listed object's first
    read of its end fetches at most a quarter of it (``cap``); a suffix read (an object named
    by its URL) knows no size beforehand."""
    cap = depth if cap is None else cap
    first = 1 if depth <= min(FIRST_TAIL_BYTES, cap) else 2
    learned = min(depth + depth // TAIL_SLACK, cap)
    return first, 1 if depth <= learned else 2


class S3Requests:
    """Requests bagkit's S3 client sends, by operation (every attempt: botocore's
    ``before-send`` event)."""

    def __init__(self, url: str) -> None:
        from fsspec.asyn import sync

        from bagkit.storage.filesystems import filesystem

        self.counts: Counter[str] = Counter()
        fs = filesystem(url)[0]
        sync(fs.loop, fs.set_session)
        fs.s3.meta.events.register("before-send.s3", self._sent)

    def _sent(self, event_name: str, **_: object) -> None:
        self.counts[event_name.rsplit(".", 1)[-1]] += 1


def test_requests_of_info_are_what_it_must_read(
    moto_store: Store, http_store: tuple[Store, HttpStore]
) -> None:
    """``info`` of a bag named by its URL makes no HEAD: a suffix read gives an object's size
    and ETag with its end. Requests per bag follow from what must be read: metadata.yaml
    whole, each MCAP's tail from its summary (a bare file: from its rosbag2 record), one
    request when the guess holds it; on S3 a bag's prefix is listed once (sizes and ETags:
    its objects are then read by plain ranges, metadata.yaml in one)."""
    golden = Path(__file__).resolve().parents[2] / "fixtures" / "nominal" / "golden"
    mcap = next(golden.glob("*.mcap"))
    yaml = (golden / "metadata.yaml").stat().st_size
    summary, record = tail_depths(mcap)
    bare_first = 1 + (summary > FIRST_TAIL_BYTES) + (record > FIRST_TAIL_BYTES)
    bare = (bare_first, first_then_learned(record)[1])
    listed_mcap = first_then_learned(summary, mcap.stat().st_size // TAIL_SHARE)
    http_yaml, http_mcap = first_then_learned(yaml), first_then_learned(summary)
    s3, objects = S3Requests(moto_store.base), http_store[1]
    for store in (moto_store, http_store[0]):
        for i in (1, 2):  # a fresh kind: nothing learned of it yet
            store.put(golden, f"counted/g/g{i}")
            store.put(mcap, f"counted/m/m{i}.mcap")
    for i in (0, 1):
        for url, s3_gets, listings, http_gets in (
            (f"counted/g/g{i + 1}", 1 + listed_mcap[i], 1, http_yaml[i] + http_mcap[i]),
            (f"counted/m/m{i + 1}.mcap", bare[i], 0, bare[i]),
        ):
            sent = Counter(s3.counts)
            bag_info(f"{moto_store.base}/{url}")
            want = {"GetObject": s3_gets, "ListObjectsV2": listings}
            assert {**want, **(s3.counts - sent)} == want, url
            answered = dict(objects.requests)
            bag_info(f"{http_store[0].base}/{url}")
            sent_http = {m: n - answered.get(m, 0) for m, n in objects.requests.items()}
            assert {"HEAD": 0, **sent_http} == {"HEAD": 0, "GET": http_gets}, url


def test_a_server_without_suffix_ranges_is_asked_for_the_size(
    http_store: tuple[Store, HttpStore], local_bags: Path
) -> None:
    """A server that sends the whole object for ``bytes=-N`` (but takes ``bytes=a-b``): the
    object is not read whole, it is asked for its size (a HEAD) and read by ranges."""
    store, objects = http_store
    file = local_bags / "fleet" / "a" / "a_0.mcap"
    assert file.stat().st_size > FIRST_TAIL_BYTES  # the whole object is more than the suffix
    store.put(file, "nosuffix/n/a.mcap")
    objects.faults["/nosuffix/n/a.mcap"] = Faults(no_suffix=True)
    answered = dict(objects.requests)
    try:
        remote = bag_info(f"{store.base}/nosuffix/n/a.mcap")
    finally:
        del objects.faults["/nosuffix/n/a.mcap"]
    sent = {m: n - answered.get(m, 0) for m, n in objects.requests.items()}
    local = bag_info(file)
    assert remote.message_count == local.message_count > 0
    assert [t.count for t in remote.topics] == [t.count for t in local.topics]
    assert sent["HEAD"] == 1 and sent["GET"] >= 2


def test_a_missing_object_costs_its_get_and_a_listing_a_missing_bucket_its_get(
    moto_store: Store,
) -> None:
    """A ``.mcap`` URL with nothing there: its suffix GET (404), then one listing (a prefix
    named so would be a bag); where S3 says the bucket does not exist, nothing is listed.
    Either way the command's error is one line naming the URL (tests/storage/
    test_storage_faults.py)."""
    from bagkit.storage.paths import UrlPath

    s3 = S3Requests(moto_store.base)
    for url, want in (
        (f"{moto_store.base}/missing/m/none.mcap", {"GetObject": 1, "ListObjectsV2": 1}),
        ("s3://no-such-bucket-counted/m/none.mcap", {"GetObject": 1}),
    ):
        sent = Counter(s3.counts)
        assert not UrlPath(url).exists()
        assert dict(s3.counts - sent) == want, url
    # What that listing is for: a bag's prefix named like a file.
    golden = Path(__file__).resolve().parents[2] / "fixtures" / "nominal" / "golden"
    moto_store.put(golden, "missing/d/bag.mcap")
    sent = Counter(s3.counts)
    assert UrlPath(f"{moto_store.base}/missing/d/bag.mcap").is_dir()
    assert dict(s3.counts - sent) == {"GetObject": 1, "ListObjectsV2": 1}
