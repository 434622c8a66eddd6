"""Seeded mutations of rosbag2's compressed files, read through BagReader (every message, every
chunk, the last messages): a ``.db3.zstd``/``.mcap.zstd`` file with flipped or cut bytes, and a
message-compressed ``.db3`` whose payloads are mutated in place. Nothing but a BagkitError may
come out, payloads that do not decompress are counted, every run ends."""

from __future__ import annotations

import os
import random
import sqlite3
import sys
from pathlib import Path

import pytest

from bagkit.bag import BagReader
from bagkit.errors import BagkitError

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_bag_compression import T0, write_compressed
from test_bag_fuzz import _mutate

RUNS = int(os.environ.get("BAGKIT_FUZZ_RUNS", "400")) // 4
SEED = os.environ.get("BAGKIT_FUZZ_SEED", "bagkit")


def _read(path: Path) -> int:
    """Read everything; return how many messages came out."""
    with BagReader(path, allow_empty=True) as bag:
        count = sum(1 for _ in bag.messages())
        for chunk in bag.chunks():
            for topic in chunk.message_index:
                _, starts, lengths = chunk.payloads(topic)
                assert ((starts >= 0) & (starts + lengths <= len(chunk.records))).all()
        bag.last_messages(list(bag.topics), T0 + 10**12)
        _ = bag.problems
    return count


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_mutated_zstd_files(tmp_path: Path, storage: str) -> None:
    bag = write_compressed(tmp_path / "bag", storage, "file", n=40)
    (stored,) = bag.glob("*.zstd")
    data = stored.read_bytes()
    rng = random.Random(f"{SEED}-{storage}-file")
    outcomes = {"read": 0, "error": 0}
    for run in range(RUNS):
        stored.write_bytes(_mutate(data, rng))
        try:
            _read(bag)
            outcomes["read"] += 1
        except BagkitError:
            outcomes["error"] += 1
        except Exception as exc:  # pragma: no cover - the failure this test exists for
            raise AssertionError(f"run {run}: {type(exc).__name__}: {exc}") from exc
    assert outcomes["error"]  # a damaged zstd stream is refused, one error


def test_mutated_zstd_payloads(tmp_path: Path) -> None:
    bag = write_compressed(tmp_path / "bag", "sqlite3", "message", n=40)
    (db3,) = bag.glob("*.db3")
    pristine = db3.read_bytes()
    rng = random.Random(f"{SEED}-payloads")
    lost = 0
    for run in range(RUNS):
        db3.write_bytes(pristine)
        db = sqlite3.connect(db3)
        rows = db.execute("SELECT rowid, data FROM messages").fetchall()
        for rowid, data in rng.sample(rows, 3):
            db.execute("UPDATE messages SET data = ? WHERE rowid = ?", (_mutate(data, rng), rowid))
        db.commit()
        db.close()
        try:
            lost += 44 - _read(bag)
        except Exception as exc:  # pragma: no cover - the failure this test exists for
            raise AssertionError(f"run {run}: {type(exc).__name__}: {exc}") from exc
    assert lost  # some mutated frames do not decompress: left out, counted in problems
