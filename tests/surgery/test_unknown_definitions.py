"""Topics whose definition is not known (a Foxy .db3 of a type no distribution ships,
rosbag2's MCAP schema of encoding ``unknown``) keep it unknown through convert and filter:
rosbag2's ``unknown`` encoding without text, no type hash made up, not an empty ``ros2msg``
text (a message without fields, which the payloads then contradict)."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import yaml
from mcap.reader import make_reader
from mcap.writer import Writer as McapWriter
from rosbags.rosbag2 import Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from surgery_samples import run_here

THING = "my_robot_msgs/msg/Thing"
T0 = 1_650_000_000_000_000_000


def _payloads() -> list[bytes]:
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg("float64 x\nstring label", THING))
    thing = store.types[THING]
    return [bytes(store.serialize_cdr(thing(x=i / 4, label=f"t{i}"), THING)) for i in range(5)]


def _foxy_db3(path: Path) -> Path:
    """A .db3 of /thing that stores neither its definition nor a type hash (as Foxy's)."""
    with Writer(path, version=8) as writer:
        conn = writer.add_connection("/thing", THING, msgdef="float64 x\nstring label", rihs01="x")
        for i, data in enumerate(_payloads()):
            writer.write(conn, T0 + i * 10**8, data)
    (db3,) = path.glob("*.db3")
    db = sqlite3.connect(db3)
    db.execute("DROP TABLE message_definitions")
    db.execute("UPDATE topics SET type_description_hash = ''")
    db.commit()
    db.close()
    metadata = path / "metadata.yaml"
    metadata.write_text(metadata.read_text().replace("type_description_hash: x", ""))
    return path


def _unknown_schema_mcap(path: Path) -> Path:
    """One MCAP file as rosbag2 writes a type whose definition it did not find."""
    with path.open("wb") as stream:
        writer = McapWriter(stream)
        writer.start(profile="ros2", library="test")
        schema = writer.register_schema(THING, "unknown", b"")
        channel = writer.register_channel("/thing", "cdr", schema)
        for i, data in enumerate(_payloads()):
            writer.add_message(channel, T0 + i * 10**8, data, T0 + i * 10**8)
        writer.finish()
    return path


def _mcap_schemas(bag: Path) -> set[tuple[str, str, bytes]]:
    found = set()
    for file in sorted(bag.glob("*.mcap")):
        with file.open("rb") as stream:
            summary = make_reader(stream).get_summary()
            assert summary is not None
            found |= {(s.name, s.encoding, s.data) for s in summary.schemas.values()}
    return found


def _healthy(bag: Path) -> None:
    done = run_here("doctor", str(bag), "--deep")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "/thing: not decoded" in done.stdout


def test_convert_keeps_an_unknown_definition_unknown(tmp_path: Path) -> None:
    foxy = _foxy_db3(tmp_path / "foxy")
    _healthy(foxy)
    assert run_here("convert", str(foxy), "-o", str(tmp_path / "m")).returncode == 0
    assert _mcap_schemas(tmp_path / "m") == {(THING, "unknown", b"")}
    _healthy(tmp_path / "m")
    done = run_here("convert", str(foxy), "-o", str(tmp_path / "s"), "-s", "sqlite3")
    assert done.returncode == 0, done.stderr
    db = sqlite3.connect(tmp_path / "s" / "s.db3")
    rows = db.execute(
        "SELECT topic_type, encoding, encoded_message_definition, type_description_hash "
        "FROM message_definitions"
    ).fetchall()
    hashes = db.execute("SELECT type_description_hash FROM topics").fetchall()
    db.close()
    assert rows == [(THING, "unknown", "", "")] and hashes == [("",)]
    metadata = yaml.safe_load((tmp_path / "s" / "metadata.yaml").read_text())
    (topic,) = metadata["rosbag2_bagfile_information"]["topics_with_message_count"]
    assert topic["message_count"] == 5 and not topic["topic_metadata"]["type_description_hash"]
    _healthy(tmp_path / "s")


def test_filter_keeps_rosbag2_s_unknown_schema(tmp_path: Path) -> None:
    source = _unknown_schema_mcap(tmp_path / "rec.mcap")
    done = run_here("filter", str(source), "-o", str(tmp_path / "cut"), "--start", "0.2")
    assert done.returncode == 0, done.stderr
    assert _mcap_schemas(tmp_path / "cut") == {(THING, "unknown", b"")}
    _healthy(tmp_path / "cut")
