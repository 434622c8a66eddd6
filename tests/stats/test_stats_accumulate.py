"""TopicAccumulator: bulk and general paths agree; a hostile payload costs that message only."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pytest
from rosbags_oracle import (
    RTOL,
    TYPESTORE,
    RawTopic,
    check_topic,
    diagnostics_data,
    imu_data,
    scan_data,
    write_bag,
)

from bagkit.decode import MessageTypes, leaf_fields
from bagkit.decode.layout import CdrLayout
from bagkit.stats import accumulate as accumulate_module
from bagkit.stats import summarize


def test_fast_path_is_taken_and_agrees_with_general_path(
    bag: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    decoded_one_by_one: list[str] = []
    general = accumulate_module.TopicAccumulator.add_payloads

    def counting(self: accumulate_module.TopicAccumulator, payloads: Iterable[bytes]) -> None:
        payloads = list(payloads)
        decoded_one_by_one.extend(self.topic for _ in payloads)
        general(self, payloads)

    monkeypatch.setattr(accumulate_module.TopicAccumulator, "add_payloads", counting)
    fast = summarize([bag])
    # Only the type with sequences of messages goes through the general decoder.
    assert set(decoded_one_by_one) == {"/diagnostics"}

    decoded_one_by_one.clear()
    monkeypatch.setattr(accumulate_module, "ROW_BATCH", 100)  # many batches to merge
    slow = summarize([bag], bulk=False)
    assert set(decoded_one_by_one) == {"/imu/data", "/scan", "/diagnostics", "/flag"}
    assert len(fast.topics) == len(slow.topics)
    for a, b in zip(fast.topics, slow.topics, strict=True):
        assert (a.topic, a.count, a.rate_hz) == (b.topic, b.count, b.rate_hz)
        for fa, fb in zip(a.fields, b.fields, strict=True):
            assert (fa.field, fa.count, fa.nan_count, fa.min, fa.max) == (
                fb.field,
                fb.count,
                fb.nan_count,
                fb.min,
                fb.max,
            )
            for x, y in ((fa.mean, fb.mean), (fa.std, fb.std)):
                assert (x is None and y is None) or x == pytest.approx(y, rel=RTOL, abs=1e-12)


def _with_length(payload: bytes, offset: int, length: int) -> bytes:
    data = bytearray(payload)
    data[offset : offset + 4] = struct.pack("<I", length)
    return bytes(data)


def _serialized(msg: object, type_name: str) -> bytes:
    return bytes(TYPESTORE.serialize_cdr(msg, type_name))


def _hostile_payloads() -> dict[str, list[bytes]]:
    """Per topic, payloads whose string or sequence length the payload cannot hold."""
    rng = np.random.default_rng(3)
    imu = imu_data(rng, 1).messages[0][1]
    imu.header.frame_id = "imu"  # type: ignore[attr-defined]
    imu_payload = _serialized(imu, "sensor_msgs/msg/Imu")
    scan = scan_data(rng, 1).messages[0][1]
    scan.header.frame_id = "ab"  # type: ignore[attr-defined]
    scan_payload = _serialized(scan, "sensor_msgs/msg/LaserScan")
    assert struct.unpack_from("<I", scan_payload, 48)[0] == len(scan.ranges)  # type: ignore[attr-defined]
    diagnostics = diagnostics_data(rng, 1).messages[0][1]
    diagnostics.header.frame_id = "ab"  # type: ignore[attr-defined]
    diagnostics_payload = _serialized(diagnostics, "diagnostic_msgs/msg/DiagnosticArray")
    return {
        "/imu/data": [  # header.frame_id's length at 12
            _with_length(imu_payload, 12, 2**31),
            _with_length(imu_payload, 12, 2**32 - 1),
            _with_length(imu_payload, 12, len(imu_payload)),
            imu_payload[:50],
        ],
        "/scan": [  # ranges' count at 48
            _with_length(scan_payload, 48, 2**31),
            _with_length(scan_payload, 48, 2**32 - 1),
        ],
        "/diagnostics": [  # status' count at 20
            _with_length(diagnostics_payload, 20, 2**31),
            _with_length(diagnostics_payload, 20, len(diagnostics_payload)),
        ],
    }


@pytest.mark.parametrize("bulk", [True, False])
def test_hostile_payloads_cost_their_message_only(tmp_path: Path, bulk: bool) -> None:
    """Counted per topic (``undecodable``, a problem line); every other message's statistics
    still equal the oracle's."""
    rng = np.random.default_rng(8)
    topics = {
        "/imu/data": imu_data(rng, 600),
        "/scan": scan_data(rng, 40),
        "/diagnostics": diagnostics_data(rng, 30),
    }
    hostile = _hostile_payloads()
    raw = {
        topic: RawTopic(
            topics[topic].type,
            [(topics[topic].messages[10 * i][0] + 1, p) for i, p in enumerate(payloads)],
        )
        for topic, payloads in hostile.items()
    }
    bag = write_bag(tmp_path / "hostile", topics, raw=raw)

    result = summarize([bag], bulk=bulk)

    assert [t.topic for t in result.topics] == sorted(topics)
    for stats in result.topics:
        bad = len(hostile[stats.topic])
        assert stats.count == len(topics[stats.topic].messages) + bad
        assert stats.undecodable == bad
        check_topic(stats, topics[stats.topic])
    assert sorted(p.split(" (")[0] for p in result.problems) == [
        f"{topic}: {len(hostile[topic])} messages could not be decoded" for topic in sorted(hostile)
    ]
    assert result.skipped == {}


def test_the_cli_warns_and_summarizes_the_rest(tmp_path: Path) -> None:
    """``bagkit stats summary`` on hostile payloads: exit 0, one warning line per topic, the
    counts in the JSON, no traceback."""
    rng = np.random.default_rng(9)
    data = imu_data(rng, 100)
    hostile = _hostile_payloads()["/imu/data"]
    raw = {"/imu/data": RawTopic(data.type, [(data.messages[5][0] + 1, p) for p in hostile])}
    bag = write_bag(tmp_path / "hostile", {"/imu/data": data}, raw=raw)
    bagkit = str(Path(sys.executable).with_name("bagkit"))
    run = subprocess.run(
        [bagkit, "stats", "summary", str(bag), "--format", "json"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    assert run.stderr.startswith("warning: /imu/data: 4 messages could not be decoded")
    assert len(run.stderr.splitlines()) == 1 and "Traceback" not in run.stderr
    (topic,) = json.loads(run.stdout)["topics"]
    assert (topic["count"], topic["undecodable"]) == (104, 4)


def test_spans_outside_the_chunk_are_counted_not_read() -> None:
    types = MessageTypes.from_definitions({})
    name = types.resolve("std_msgs/msg/Bool")
    leaves = leaf_fields(types.typestore, name)
    layout = CdrLayout.of(types.typestore, name)
    for bulk_layout in (layout, None):
        accumulator = accumulate_module.TopicAccumulator(
            "/flag", name, leaves, layout=bulk_layout, types=types, signature=tuple(leaves)
        )
        records = b"\x00\x01\x00\x00\x01\x00\x01\x00\x00\x00"
        starts = np.array([0, 5, 8, -1, 2**40], dtype=np.int64)
        lengths = np.array([5, 5, 5, 5, 5], dtype=np.int64)
        accumulator.add_spans(records, starts, lengths)
        (flag,) = accumulator.result().fields
        assert (flag.count, flag.mean) == (2, 0.5)
        assert accumulator.failures == 3
        assert accumulator.first_failure == "payload outside its chunk"


@pytest.mark.parametrize("bulk", [True, False])
@pytest.mark.parametrize(
    "type_name",
    ["sensor_msgs/msg/Imu", "sensor_msgs/msg/LaserScan", "diagnostic_msgs/msg/DiagnosticArray"],
)
def test_mutated_payloads_never_end_a_topic(type_name: str, bulk: bool) -> None:
    """A fixed-seed fuzz: random bytes, random u32s at aligned offsets (lengths), cut and
    extended payloads. Every message is either decoded or counted; nothing raises."""
    rng = np.random.default_rng(12)
    make = {
        "sensor_msgs/msg/Imu": imu_data,
        "sensor_msgs/msg/LaserScan": scan_data,
        "diagnostic_msgs/msg/DiagnosticArray": diagnostics_data,
    }[type_name]
    payloads = [_serialized(msg, type_name) for _, msg in make(rng, 40).messages]
    mutated = []
    for i in range(1500):
        data = bytearray(payloads[i % len(payloads)])
        kind = i % 4
        if kind == 0:
            data[int(rng.integers(4, len(data)))] = int(rng.integers(0, 256))
        elif kind == 1:
            at = int(rng.integers(1, len(data) // 4)) * 4
            value = int(rng.choice([2**31, 2**32 - 1, len(data), int(rng.integers(0, 64))]))
            data[at : at + 4] = value.to_bytes(4, "little")
        elif kind == 2:
            data = data[: int(rng.integers(0, len(data)))]
        else:
            data += bytes(int(rng.integers(1, 16)))
        mutated.append(bytes(data))
    types = MessageTypes.from_definitions({})
    name = types.resolve(type_name)
    leaves = [leaf for leaf in leaf_fields(types.typestore, name) if leaf.numeric]
    layout = CdrLayout.of(types.typestore, name) if bulk else None
    accumulator = accumulate_module.TopicAccumulator(
        "/t", name, leaves, layout=layout, types=types, signature=tuple(leaves)
    )
    records = b"".join(mutated)
    lengths = np.array([len(p) for p in mutated], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    accumulator.add_spans(records, starts, lengths)
    accumulator.add_times(np.arange(len(mutated), dtype=np.int64))
    stats = accumulator.result()
    assert 0 < accumulator.failures < len(mutated)
    # Each decoded message gave one value (or NaN) to every scalar field.
    scalar = next(f for f in stats.fields if f.field == "header.stamp.sec")
    assert scalar.count + scalar.nan_count == len(mutated) - accumulator.failures
