"""Every rosbag2 interop bag: the per-topic counts the storage holds, or a clear error."""

from __future__ import annotations

import re
import sqlite3
from collections import Counter
from pathlib import Path

import pytest
from mcap.reader import make_reader

from bagkit.errors import BagkitError
from bagkit.stats import NothingToSummarizeError, summarize


def _storage_files(bag: Path) -> list[Path]:
    if bag.is_file():
        return [bag]
    return sorted(p for p in bag.iterdir() if p.suffix in (".mcap", ".db3"))


def _stored_counts(bag: Path) -> Counter[str]:
    """Messages per topic, read with the mcap library and sqlite3 (not with bagkit)."""
    counts: Counter[str] = Counter()
    for file in _storage_files(bag):
        if file.suffix == ".mcap":
            with open(file, "rb") as f:
                reader = make_reader(f)
                summary = reader.get_summary()
                for channel in summary.channels.values() if summary else ():
                    counts[channel.topic] += 0
                for _, channel, _ in reader.iter_messages():
                    counts[channel.topic] += 1
        else:
            db = sqlite3.connect(f"file:{file}?mode=ro&immutable=1", uri=True)
            try:
                query = (
                    "SELECT topics.name, COUNT(messages.id) FROM topics "
                    "LEFT JOIN messages ON messages.topic_id = topics.id GROUP BY topics.name"
                )
                for name, count in db.execute(query):
                    counts[name] += count
            finally:
                db.close()
    return counts


def _interop_bags(root: Path) -> list[Path]:
    directories = {p.parent for p in root.rglob("*") if p.suffix in (".mcap", ".db3")}
    directories |= {p.parent for p in root.rglob("metadata.yaml")}
    files = [p for p in root.rglob("*") if p.suffix in (".mcap", ".db3")]
    return sorted(directories) + sorted(files)


# Bags that hold nothing decodable, on purpose or by age, and what the error must say.
EXPECTED_ERRORS = {
    "wrong_rmw_test": "wrong_format|no message definition",
    "empty_bag": "no messages",
}


def test_every_interop_bag(interop_dir: Path) -> None:
    bags = _interop_bags(interop_dir)
    assert len(bags) > 40
    summarized = 0
    for bag in bags:
        name = str(bag.relative_to(interop_dir))
        stored = _stored_counts(bag)
        try:
            result = summarize([bag])
        except NothingToSummarizeError as exc:
            expected = next((v for k, v in EXPECTED_ERRORS.items() if k in name), None)
            if expected is None:
                # Old .db3 bags store no definitions: every topic must be named as undecodable.
                assert bag.suffix == ".db3" or any(bag.glob("*.db3")), (name, str(exc))
                assert all(topic in str(exc) for topic in stored), (name, str(exc))
            else:
                assert re.search(expected, str(exc)), (name, str(exc))
            continue
        summarized += 1
        reported = {t.topic: t.count for t in result.topics}
        assert reported.keys() | result.skipped.keys() == stored.keys(), name
        for topic, count in reported.items():
            assert count == stored[topic], (name, topic)
        for topic, reason in result.skipped.items():
            assert reason, (name, topic)
    assert summarized > 25


def test_not_a_bag_is_a_bagkit_error(tmp_path: Path) -> None:
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all")
    with pytest.raises(BagkitError) as info:
        summarize([junk])
    assert info.value.exit_code == 2
