"""``bagkit catalog``: rows checked against the ``mcap`` package's own summary reading; an
update reopens only the bags that changed (opens counted); queries by topic and time."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from distributed import Client
from fleet_bags import T0, write_bag
from mcap.reader import make_reader

from bagkit.fleet import describe as describe_module
from bagkit.fleet.catalog import (
    complete_update,
    plan_update,
    query,
    read_catalog,
    to_frame,
    unknown_topics,
    write_catalog,
)
from bagkit.selection.query import Query

BAGKIT = str(Path(sys.executable).with_name("bagkit"))


def _mcap_summary(bag: Path) -> tuple[dict[str, int], int, int]:
    """Per-topic counts, first and last log time, as the mcap package reads them."""
    (file,) = bag.glob("*.mcap")
    with file.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None and summary.statistics is not None
    stats = summary.statistics
    counts = {summary.channels[cid].topic: n for cid, n in stats.channel_message_counts.items()}
    return counts, stats.message_start_time, stats.message_end_time


def _update(root: Path, output: Path, client: Client | None) -> tuple[pd.DataFrame, list[str]]:
    plan = plan_update([root], output)
    frame = complete_update(plan, client)
    write_catalog(frame, output)
    return frame, plan.to_open


def test_rows_match_the_mcap_summary(
    client: Client, fleet_dir: Path, fleet_bags: list[Path], tmp_path: Path
) -> None:
    root = tmp_path / "root"
    shutil.copytree(fleet_dir, root)
    (root / "broken.mcap").write_bytes(b"\x89MCAP0\r\n" + b"\0" * 50)
    frame, opened = _update(root, tmp_path / "catalog.parquet", client)
    assert len(opened) == len(fleet_bags) + 1
    frame = read_catalog(tmp_path / "catalog.parquet")  # what pandas reads back
    for bag in (p for p in root.rglob("flight_*") if p.is_dir()):
        counts, start, end = _mcap_summary(bag)
        rows = frame[frame["path"] == str(bag)]
        assert dict(zip(rows["topic"], rows["count"], strict=True)) == counts
        assert (rows["start"] == pd.Timestamp(start, unit="ns", tz="UTC")).all()
        assert (rows["end"] == pd.Timestamp(end, unit="ns", tz="UTC")).all()
        assert (rows["duration"] == (end - start) / 1e9).all()
        assert (rows["size"] == sum(f.stat().st_size for f in bag.iterdir())).all()
        assert (rows["compression"] == "zstd").all() and (rows["problems"] == "").all()
    broken = frame[frame["path"] == str(root / "broken.mcap")]
    assert len(broken) == 1 and pd.isna(broken["topic"].iloc[0])
    assert broken["problems"].iloc[0] != ""


def test_update_reopens_only_what_changed(
    fleet_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    root = tmp_path / "root"
    shutil.copytree(fleet_dir, root)
    output = tmp_path / "catalog.parquet"
    opens: list[str] = []
    real = describe_module.BagReader

    def counting(path: str, **kwargs: bool) -> object:
        opens.append(str(path))
        return real(path, **kwargs)

    monkeypatch.setattr(describe_module, "BagReader", counting)
    first, _ = _update(root, output, None)
    assert len(opens) == 6
    opens.clear()
    again, opened = _update(root, output, None)
    assert opens == [] and opened == []
    pd.testing.assert_frame_equal(again, first)
    # One bag rewritten with more messages, one removed, one added.
    changed = root / "flight_1"
    shutil.rmtree(changed)
    write_bag(changed, seed=1, n=999, t0=T0)
    shutil.rmtree(root / "flight_2")
    write_bag(root / "day2" / "flight_9", seed=9, n=100, t0=T0)
    third, _ = _update(root, output, None)
    assert sorted(opens) == sorted([str(changed), str(root / "day2" / "flight_9")])
    rows = third[third["path"] == str(changed)]
    assert dict(zip(rows["topic"], rows["count"], strict=True)) == _mcap_summary(changed)[0]
    assert str(root / "flight_2") not in set(third["path"])
    assert set(third["path"]) == {str(p) for p in root.rglob("flight_*") if p.is_dir()}


def test_query_by_topic_and_time(fleet_dir: Path, tmp_path: Path) -> None:
    frame, _ = _update(fleet_dir, tmp_path / "catalog.parquet", None)
    hour = pd.Timedelta(hours=1)
    t0 = pd.Timestamp(T0, unit="ns", tz="UTC")
    # Bag i runs from T0 + i hours for a few seconds.
    last = t0 + 3 * hour + pd.Timedelta(seconds=1)
    window = Query.create("/temp*", start=t0 + 2 * hour, end=last)
    got = query(frame, window)
    assert sorted(Path(p).name for p in got["path"]) == ["flight_2", "flight_3"]
    assert set(got["topic"]) == {"/temperature"}
    assert len(query(frame, Query.create("/nothing"))) == 0
    assert len(query(frame)) == 12


def test_query_by_a_service_or_an_action_name_and_unknown_names() -> None:
    topics = ["/reset/_service_event", "/fib/_action/feedback", "/fib/_action/status"]
    topics += ["/imu/data", "/reset_more", "/fibonacci/_action/status"]
    t0 = pd.Timestamp(T0, unit="ns", tz="UTC")
    frame = pd.DataFrame({"path": "bag", "topic": topics, "count": 1, "start": t0, "end": t0})
    assert query(frame, Query.create("/reset"))["topic"].tolist() == [topics[0]]
    assert query(frame, Query.create("fib"))["topic"].tolist() == topics[1:3]
    assert unknown_topics(frame, Query.create(["/fib", "/imu/dta"])) == [
        f"no bag of the catalogue has /imu/dta (did you mean /imu/data? it has "
        f"{', '.join(sorted(topics))})"
    ]


def test_cli_builds_updates_and_queries(client: Client, fleet_dir: Path, tmp_path: Path) -> None:
    output = tmp_path / "fleet.parquet"
    address = client.scheduler.address
    run = [BAGKIT, "catalog", str(fleet_dir), "-o", str(output), "--scheduler", address]
    first = subprocess.run(run, capture_output=True, text=True, timeout=120, check=True)
    assert "local Dask cluster" not in first.stderr
    assert "6 read, 0 unchanged" in first.stderr
    second = subprocess.run(run, capture_output=True, text=True, timeout=120, check=True)
    assert "0 read, 6 unchanged" in second.stderr and "Dask" not in second.stderr
    found = subprocess.run(
        [BAGKIT, "catalog", "query", str(output), "-t", "/imu/data", "--format", "json"],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    rows = json.loads(found.stdout)
    frame = pd.read_parquet(output)
    expected = frame[frame["topic"] == "/imu/data"]
    assert [r["count"] for r in rows] == expected["count"].tolist()
    for when in ("yesterday-ish", "nan", "", "10"):  # 10: an offset, no bag start to count from
        bad = subprocess.run(
            [BAGKIT, "catalog", "query", str(output), "--start", when],
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
        assert bad.returncode == 2 and bad.stderr.startswith(f"error: bad --start {when!r}"), when


def test_an_empty_bag_has_no_times(tmp_path: Path) -> None:
    """rosbags' empty bag (topics, no messages): its rows count 0 and have no start or end
    (not 1970-01-01, which a time query would match)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    with Writer(tmp_path / "empty", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        writer.add_connection(
            "/imu", "sensor_msgs/msg/Imu", typestore=get_typestore(Stores.ROS2_JAZZY)
        )
    (row,) = to_frame(describe_module.describe_bag(str(tmp_path / "empty"))).to_dict("records")
    assert (row["topic"], row["count"], row["problems"]) == ("/imu", 0, "")
    assert pd.isna(row["start"]) and pd.isna(row["end"])
