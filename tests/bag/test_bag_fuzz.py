"""Seeded mutations of a small valid MCAP file (bytes flipped, fields overwritten with extreme
values, cuts, spliced records), each read through BagReader (index, every message, every chunk's
payload spans): nothing but a BagkitError may come out, and every run ends."""

from __future__ import annotations

import os
import random
import struct
from collections.abc import Callable
from pathlib import Path

import pytest

from bagkit.bag import BagReader
from bagkit.errors import BagkitError

# BAGKIT_FUZZ_RUNS=20000 (and BAGKIT_FUZZ_SEED) for a longer run on demand.
RUNS = int(os.environ.get("BAGKIT_FUZZ_RUNS", "400"))
SEED = os.environ.get("BAGKIT_FUZZ_SEED", "bagkit")
EXTREMES = [0, 1, 2**31, 2**32 - 1, 2**62, 2**63, 2**64 - 1]


def _mutate(data: bytes, rng: random.Random) -> bytes:
    out = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        if len(out) < 80:
            break
        kind = rng.randrange(5)
        at = rng.randrange(8, len(out) - 8)
        if kind == 0:
            out[at] ^= 1 << rng.randrange(8)
        elif kind == 1:
            struct.pack_into("<Q", out, at, rng.choice(EXTREMES))
        elif kind == 2:
            struct.pack_into("<I", out, at, rng.choice(EXTREMES) & 0xFFFFFFFF)
        elif kind == 3:
            del out[at:]
            out += data[-rng.randint(0, 40) :] if rng.random() < 0.5 else b""
        else:
            length = rng.randint(1, 64)
            source = rng.randrange(0, len(data) - length)
            out[at : at + length] = data[source : source + length]
    return bytes(out)


def _read(path: Path) -> None:
    with BagReader(path, allow_empty=True) as bag:
        for _ in bag.messages():
            pass
        for chunk in bag.chunks():
            for topic in chunk.message_index:
                _, starts, lengths = chunk.payloads(topic)
                assert ((starts >= 0) & (starts + lengths <= len(chunk.records))).all()
        _ = bag.problems


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_mutated_files_raise_only_bagkit_errors(
    write_sample_bag: Callable[..., Path], tmp_path: Path, compression: str
) -> None:
    bag = write_sample_bag(n_imu=60, chunk_size=3_000, compression=compression)
    data = (bag / "sample_0.mcap").read_bytes()
    rng = random.Random(f"{SEED}-{compression}")
    target = tmp_path / "fuzzed.mcap"
    outcomes = {"read": 0, "error": 0}
    for run in range(RUNS):
        target.write_bytes(_mutate(data, rng))
        try:
            _read(target)
            outcomes["read"] += 1
        except BagkitError:
            outcomes["error"] += 1
        except Exception as exc:  # pragma: no cover - the failure this test exists for
            raise AssertionError(f"run {run}: {type(exc).__name__}: {exc}") from exc
    assert outcomes["read"] > RUNS // 2  # most mutations leave something readable
