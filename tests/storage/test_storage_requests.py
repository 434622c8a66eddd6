"""How few requests a bag in storage costs: ``info`` of an MCAP fetches its closing magic,
footer and summary in one request (its header only when the summary is not enough), and
files that are cut or not ROS 2 still read as they do on disk."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.writer import Writer

from bagkit.bag import BagError, bag_info
from bagkit.storage.range_file import fetched
from tests.storage.conftest import Store
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
