"""``bagkit doctor`` on SQLite3 and zstd-compressed bags: the interop .db3 bags (metadata.yaml
against sqlite3's own reading), compressed bags, a damaged database, a wrong count."""

from __future__ import annotations

import json
import sqlite3
import sys
from pathlib import Path

import pytest
import yaml
from surgery_samples import run, run_here

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bag"))
from test_bag_compression import write_compressed


def _times(files: list[Path]) -> list[int]:
    times: list[int] = []
    for file in files:
        db = sqlite3.connect(f"file:{file}?mode=ro&immutable=1", uri=True)
        times += [t for (t,) in db.execute("SELECT timestamp FROM messages")]
        db.close()
    return times


def test_every_interop_db3_bag(interop_dir: Path) -> None:
    """No file problem; the metadata.yaml problems are exactly the fields that disagree with
    what sqlite3 itself reads."""
    bags = sorted(
        {p.parent for p in interop_dir.rglob("*.db3") if (p.parent / "metadata.yaml").exists()}
    )
    assert len(bags) >= 8
    for bag in bags:
        files = sorted(bag.glob("*.db3"))
        result = run_here("doctor", str(bag), "--deep", "--format", "json")
        report = json.loads(result.stdout)
        # rosbag2's talker test bag stores cut definitions ('uint8 level' for a Log): real.
        undecodable = [p["problem"] for p in report["problems"] if p["where"] == "bag"]
        assert all("did not decode" in p for p in undecodable), bag
        assert bool(undecodable) == (bag.name == "talker"), bag
        assert [p for p in report["problems"] if p["where"] not in ("bag", "metadata.yaml")] == []
        times = _times(files)
        info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        expected = set()
        if info["message_count"] != len(times):
            expected.add("message_count")
        if times and info["starting_time"]["nanoseconds_since_epoch"] != min(times):
            expected.add("starting_time")
        if times and info["duration"]["nanoseconds"] != max(times) - min(times):
            expected.add("duration")
        fields = {p["problem"].split(" is ")[0] for p in report["problems"] if p["where"] != "bag"}
        assert fields == expected, bag
        assert report["message_count"] == len(times)
        assert result.returncode == (1 if expected or undecodable else 0)


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
@pytest.mark.parametrize("mode", ["file", "message"])
def test_compressed_bags_are_healthy(tmp_path: Path, storage: str, mode: str) -> None:
    bag = write_compressed(tmp_path / "bag", storage, mode)
    result = run_here("doctor", str(bag), "--deep", "--format", "json")
    report = json.loads(result.stdout)
    assert result.returncode == 0 and report["problems"] == [], report
    assert report["message_count"] == 132


def test_a_count_that_metadata_yaml_gets_wrong(tmp_path: Path) -> None:
    bag = write_compressed(tmp_path / "bag", "sqlite3", "message")
    (db3,) = bag.glob("*.db3")
    db = sqlite3.connect(db3)
    db.execute("DELETE FROM messages WHERE rowid = 2")
    db.commit()
    db.close()
    result = run_here("doctor", str(bag), "--deep")
    assert result.returncode == 1
    lines = result.stdout.splitlines()
    assert "metadata.yaml: message_count is 132, the files hold 131" in lines


def test_a_damaged_database(tmp_path: Path) -> None:
    bag = write_compressed(tmp_path / "bag", "sqlite3", "message", n=3000)
    (db3,) = bag.glob("*.db3")
    data = bytearray(db3.read_bytes())
    page = 4096
    data[5 * page : 5 * page + 64] = bytes(64)  # wipe the header of a b-tree page
    db3.write_bytes(bytes(data))
    result = run("doctor", str(bag))
    assert result.returncode in (1, 2) and "Traceback" not in result.stderr
    assert "SQLite3" in result.stdout + result.stderr


def test_types_assumed_for_a_bag_without_definitions_are_one_warning(tmp_path: Path) -> None:
    """A .db3 that stores no definitions and names no distribution: one warning names every
    type decoded with Jazzy's (it was one warning per type)."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    types = ["std_msgs/msg/String", "std_msgs/msg/UInt32"]
    bag = tmp_path / "old"
    with Writer(bag, version=8) as writer:
        for n, name in enumerate(types):
            connection = writer.add_connection(f"/t{n}", name, typestore=store)
            message = store.types[name](data="x" if n == 0 else 7)
            writer.write(connection, 1_000 + n, bytes(store.serialize_cdr(message, name)))
    (db3,) = bag.glob("*.db3")
    with sqlite3.connect(db3) as db:
        db.execute("DROP TABLE message_definitions")
    db.close()
    metadata = bag / "metadata.yaml"
    metadata.write_text(
        "\n".join(line for line in metadata.read_text().splitlines() if "ros_distro" not in line)
    )
    result = run("doctor", str(bag), "--deep")
    assert result.returncode == 0, result.stdout + result.stderr
    warnings = [line for line in result.stderr.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1, result.stderr
    assert all(name in warnings[0] for name in types)
