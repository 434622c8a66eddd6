"""rosbag2's zstd-compressed bags (file and message modes) read from storage: the same
messages as rosbags' reader gives of the bag on disk."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagReader
from bagkit.storage.paths import UrlPath
from tests.storage.conftest import Store
from tests.storage.test_storage_read import cli

STORE = get_typestore(Stores.ROS2_JAZZY)
MODES = {"file": CompressionMode.FILE, "message": CompressionMode.MESSAGE}


def write_strings(path: Path, storage: StoragePlugin, mode: CompressionMode) -> Path:
    """30 std_msgs/String messages, zstd-compressed in ``mode`` by rosbags' writer."""
    writer = Writer(path, version=9, storage_plugin=storage)
    writer.set_compression(mode, CompressionFormat.ZSTD)
    string = STORE.types["std_msgs/msg/String"]
    with writer:
        text = writer.add_connection("/text", "std_msgs/msg/String", typestore=STORE)
        for i in range(30):
            data = STORE.serialize_cdr(string(data=f"message {i}"), "std_msgs/msg/String")
            writer.write(text, 1_000 + i, bytes(data))
    return path


@pytest.mark.parametrize("storage", [StoragePlugin.SQLITE3, StoragePlugin.MCAP], ids=str)
@pytest.mark.parametrize("mode", MODES)
def test_compressed_bags_in_storage(
    moto_store: Store, tmp_path: Path, storage: StoragePlugin, mode: str
) -> None:
    bag = write_strings(tmp_path / f"{mode}_{storage.name}", storage, MODES[mode])
    with Reader(bag) as reader:
        expected = [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]
    moto_store.put(bag, f"compressed/{bag.name}")
    url = f"{moto_store.base}/compressed/{bag.name}"
    with BagReader(UrlPath(url)) as remote:
        assert [(m.topic, m.log_time, m.data) for m in remote.messages()] == expected
        assert remote.problems == []
    echo = cli(["echo", url, "/text", "--format", "json", "-n", "1"], moto_store.env)
    assert echo.returncode == 0, echo.stderr
    assert json.loads(echo.stdout)["data"] == {"data": "message 0"}


def test_info_of_a_compressed_file_over_http(
    http_store: tuple[Store, object], tmp_path: Path
) -> None:
    # An HTTP server lists nothing: a .mcap.zstd URL is a bag by its name, as a .mcap's is.
    store = http_store[0]
    bag = write_strings(tmp_path / "bag", StoragePlugin.MCAP, CompressionMode.FILE)
    (stored,) = bag.glob("*.mcap.zstd")
    store.put(stored, "loose/strings.mcap.zstd")
    info = cli(["info", f"{store.base}/loose/strings.mcap.zstd", "--format", "json"], {})
    assert info.returncode == 0, info.stderr
    assert json.loads(info.stdout)["message_count"] == 30
