"""read_arrow / read_dataframe: every value of every message equals rosbags' decoding."""

from __future__ import annotations

import warnings
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pytest
from oracle import flatten, raw_messages, same
from rosbags.dataframe import get_dataframe
from rosbags.highlevel import AnyReader
from rosbags.serde import SerdeError

import bagkit
from bagkit.bag import BagReader
from bagkit.data import DataLossWarning, UndecodableTopicError, UnknownFieldError, UnknownTopicError
from bagkit.decode import DecodeError, MessageTypes

REPO = Path(__file__).resolve().parents[2]
GOLDEN = sorted(REPO.glob("fixtures/*/golden"))


Rows = list[tuple[int, int, dict[str, Any]]]


def _expected(bag: Path) -> tuple[dict[str, Rows], dict[str, int]]:
    """Per decodable topic: (log_time, publish_time, leaf values) in log-time order; and per
    topic how many messages rosbags cannot decode."""
    with BagReader(bag, allow_empty=True) as reader:
        topics = {name: info.type for name, info in reader.topics.items()}
        formats = {name: info.serialization_format for name, info in reader.topics.items()}
        types = MessageTypes.from_definitions(reader.definitions)
    canonical: dict[str, str] = {}
    for name, type_name in topics.items():
        try:
            canonical[name] = types.resolve(type_name)
        except DecodeError:
            continue
    rows: dict[str, Rows] = defaultdict(list)
    undecodable: dict[str, int] = defaultdict(int)
    for topic, log_time, publish_time, data in raw_messages(bag):
        if topic not in canonical or formats[topic] != "cdr":
            continue
        try:
            msg = types.rosbags_typestore().deserialize_cdr(data, canonical[topic])
        except SerdeError:
            undecodable[topic] += 1
            continue
        rows[topic].append(
            (log_time, publish_time, flatten(msg, types.typestore, canonical[topic]))
        )
    for found in rows.values():
        found.sort(key=lambda row: row[0])  # stable: ties keep storage order
    return rows, undecodable


def _check_bag(bag: Path, *, bulk: bool = True) -> int:
    """Compare every value; return how many were compared."""
    compared = 0
    expected, undecodable = _expected(bag)
    for topic in expected.keys() | undecodable.keys():
        rows = expected.get(topic, [])
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", DataLossWarning)
            table = bagkit.read_arrow(bag, topic, bulk=bulk)
        lost = [str(w.message) for w in caught if w.category is DataLossWarning]
        if undecodable.get(topic):
            assert lost == [
                f"{bag}: {topic}: {undecodable[topic]} messages could not be decoded"
            ] or (len(lost) == 1 and f"{topic}: {undecodable[topic]} messages" in lost[0]), lost
        else:
            assert lost == [], lost
        got = table.to_pylist()
        assert len(got) == len(rows), (bag, topic)
        for (log_time, publish_time, flat), row in zip(rows, got, strict=True):
            assert row["log_time"] == log_time and row["publish_time"] == publish_time
            leaves = [
                name for name in table.column_names if name not in ("log_time", "publish_time")
            ]
            for path in leaves:
                want = flat.get(path, [])  # a pooled leaf of empty sequences has no value
                assert same(row[path], want), (bag.name, topic, path, row[path], want)
                compared += 1
            assert set(flat) <= set(leaves), (topic, set(flat) - set(leaves))
    return compared


def test_sample_bag_equals_rosbags(sample_bag: Path) -> None:
    """NaN, inf, every integer width, bool, octets > 127, strings, fixed arrays, sequences of
    numbers, strings and structs, several frame_id lengths (several bulk groups per chunk)."""
    assert _check_bag(sample_bag) > 50_000


def test_general_path_equals_bulk_path(sample_bag: Path) -> None:
    for topic in ("/imu", "/scan", "/image", "/odom"):
        bulk = bagkit.read_arrow(sample_bag, topic)
        general = bagkit.read_arrow(sample_bag, topic, bulk=False)
        assert bulk.schema == general.schema
        assert bulk.to_pylist() == general.to_pylist() or all(
            same(a[k], b[k])
            for a, b in zip(bulk.to_pylist(), general.to_pylist(), strict=True)
            for k in a
        )


@pytest.mark.parametrize("golden", GOLDEN, ids=lambda p: p.parent.name)
def test_golden_bags_equal_rosbags(golden: Path) -> None:
    assert _check_bag(golden) > 10_000


def _interop_bags(root: Path) -> list[Path]:
    directories = {p.parent for p in root.rglob("*") if p.suffix in (".mcap", ".db3")}
    files = [p for p in root.rglob("*") if p.suffix in (".mcap", ".db3")]
    return sorted(directories) + sorted(files)


def test_interop_bags_equal_rosbags(interop_dir: Path) -> None:
    checked = 0
    for bag in _interop_bags(interop_dir):
        try:
            with BagReader(bag, allow_empty=True):
                pass
        except bagkit.errors.BagkitError:  # not a readable bag on its own (covered in tests/bag)
            continue
        checked += _check_bag(bag)
    assert checked > 1000


def test_dataframe_columns_index_and_rosbags_dataframe(tmp_path: Path) -> None:
    """The DataFrame of all fields against rosbags-dataframe's get_dataframe of the same keys."""
    bag = GOLDEN[0]
    frame = bagkit.read_dataframe(bag, "/imu/data")
    assert isinstance(frame.index, pd.DatetimeIndex) and frame.index.dtype == "datetime64[ns, UTC]"
    start = frame.index[0]
    assert frame.loc[pd.Timestamp(start.isoformat().replace("+00:00", "Z")) :].shape == frame.shape
    assert (frame.index.asi8 == frame["log_time"].to_numpy()).all()
    assert frame["log_time"].dtype == np.int64 and frame["publish_time"].dtype == np.int64
    keys = [c for c in frame.columns if "[" not in c and c not in ("log_time", "publish_time")]
    with AnyReader([bag]) as reader:
        theirs = get_dataframe(reader, "/imu/data", keys)
    theirs_ns = theirs.index.to_numpy().astype("datetime64[ns]").astype(np.int64)
    assert (theirs_ns == frame.index.asi8).all()
    for key in keys:
        assert np.array_equal(frame[key].to_numpy(), theirs[key].to_numpy()), key
    with AnyReader([bag]) as reader:
        covariance = get_dataframe(reader, "/imu/data", ["orientation_covariance"])
    ours = frame[[f"orientation_covariance[{i}]" for i in range(9)]].to_numpy()
    assert np.array_equal(ours, np.stack(covariance["orientation_covariance"].to_list()))


def test_fields_globs_subtrees_and_time_window(sample_bag: Path) -> None:
    full = bagkit.read_dataframe(sample_bag, "/imu")
    part = bagkit.read_dataframe(
        sample_bag, "/imu", ["header", "linear_acceleration.?"], start=0.05, end=0.2
    )
    assert list(part.columns) == [
        "log_time",
        "publish_time",
        "header.stamp.sec",
        "header.stamp.nanosec",
        "header.frame_id",
        "linear_acceleration.x",
        "linear_acceleration.y",
        "linear_acceleration.z",
    ]
    first = full["log_time"].iloc[0]
    inside = full[
        (full["log_time"] >= first + 50_000_000) & (full["log_time"] < first + 200_000_000)
    ]
    assert 0 < len(part) == len(inside) < len(full)
    assert part["linear_acceleration.x"].equals(inside["linear_acceleration.x"])
    absolute = bagkit.read_dataframe(
        sample_bag,
        "/imu",
        ["header.frame_id"],
        start=pd.Timestamp(first + 50_000_000),
        end=(first + 200_000_000) / 1e9,
    )
    assert len(absolute) == len(inside)


def test_unknown_topic_and_field_name_what_exists(sample_bag: Path) -> None:
    with pytest.raises(UnknownTopicError, match=r"/nope.*it has /diagnostics, /fix"):
        bagkit.read_dataframe(sample_bag, "/nope")
    with pytest.raises(UnknownFieldError, match=r"no field linear_accel\b.*linear_acceleration.x"):
        bagkit.read_dataframe(sample_bag, "/imu", ["linear_accel"])


def test_undecodable_topic(tmp_path: Path) -> None:
    from bagkit.bag import BagWriter, TopicInfo

    with BagWriter(tmp_path / "b") as bag:
        bag.add_topic(TopicInfo("/blob", "acme_msgs/msg/Blob"), definition="int32 x\nbogus_t y\n")
        bag.write("/blob", b"\x00\x01\x00\x00" + bytes(8), log_time=1)
    with pytest.raises(
        UndecodableTopicError, match=r"/blob cannot be decoded: .*acme_msgs/msg/Blob"
    ):
        bagkit.read_arrow(tmp_path / "b", "/blob")


def test_import_bagkit_stays_cheap() -> None:
    import subprocess
    import sys

    code = "import bagkit, sys; print('pandas' in sys.modules, 'pyarrow' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]
    assert isinstance(bagkit.read_arrow(GOLDEN[0], "/temperature"), pa.Table)
