"""bagkit.data.episodes and bagkit.data.matching against a pandas oracle over generated bags.

The oracle works from the values the test wrote (serialized by rosbags), never from bagkit's
decoding: runs of matching messages found with pandas, merged by a plain loop.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from ros2_messages import DB3_SCHEMA
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagReader, BagWriter, TopicInfo
from bagkit.data.episodes import Episode, episode_spans, find_episodes
from bagkit.data.matching import match_topic
from bagkit.selection.conditions import parse_condition, parse_topic_condition
from bagkit.selection.errors import SelectionError, UnknownFieldError
from bagkit.selection.windows import Window

TS = get_typestore(Stores.ROS2_JAZZY)
IMU = "sensor_msgs/msg/Imu"
DIAG = "diagnostic_msgs/msg/DiagnosticArray"
START = 1_700_000_000_000_000_000


def oracle(times: np.ndarray, matched: np.ndarray, gap_ns: int) -> list[tuple[int, int, int]]:
    frame = pd.DataFrame({"t": times, "m": matched})
    frame["run"] = (frame["m"] != frame["m"].shift()).cumsum()
    runs = frame[frame["m"]].groupby("run")["t"].agg(["first", "last", "count"])
    merged: list[list[int]] = []
    for first, last, count in runs.itertuples(index=False):
        if merged and first - merged[-1][1] < gap_ns:
            merged[-1][1] = last
            merged[-1][2] += count
        else:
            merged.append([first, last, count])
    return [(a, b, c) for a, b, c in merged]


def as_tuples(episodes: list[Episode]) -> list[tuple[int, int, int]]:
    return [(e.start_ns, e.end_ns, e.count) for e in episodes]


def spans(times: np.ndarray, matched: np.ndarray, gap_ns: int = 0) -> list[tuple[int, ...]]:
    return [tuple(row) for row in episode_spans(times, matched, gap_ns).tolist()]


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("gap_ns", [0, 1, 5, 40, 10**9])
def test_episode_spans_equal_the_pandas_oracle(seed: int, gap_ns: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 400))
    times = np.cumsum(rng.integers(0, 12, n)).astype(np.int64)  # ties too
    matched = rng.random(n) < rng.uniform(0.05, 0.9)
    assert spans(times, matched, gap_ns) == oracle(times, matched, gap_ns)


def test_episode_boundaries() -> None:
    times = np.array([0, 10, 20, 30, 40, 50])
    matched = np.array([True, True, False, True, False, True])
    assert spans(times, matched) == [(0, 10, 2), (30, 30, 1), (50, 50, 1)]
    # 30 - 10 = 20: a gap of 20 keeps them apart (merge only when closer), 21 merges.
    assert spans(times, matched, 20) == [(0, 10, 2), (30, 30, 1), (50, 50, 1)]
    assert spans(times, matched, 21) == [(0, 50, 4)]
    assert spans(times, np.zeros(6, bool), 10**9) == []


def _imu(z: float, i: int) -> bytes:
    t = TS.types
    vec = t["geometry_msgs/msg/Vector3"]
    msg = t[IMU](
        header=t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=i, nanosec=0), frame_id="imu"
        ),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=vec(x=0.0, y=0.0, z=0.0),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=vec(x=0.0, y=0.0, z=z),
        linear_acceleration_covariance=np.zeros(9),
    )
    return bytes(TS.serialize_cdr(msg, IMU))


def _diagnostics(levels: list[int]) -> bytes:
    t = TS.types
    status = [
        t["diagnostic_msgs/msg/DiagnosticStatus"](
            level=level, name=f"s{k}", message="", hardware_id="hw", values=[]
        )
        for k, level in enumerate(levels)
    ]
    header = t["std_msgs/msg/Header"](
        stamp=t["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id=""
    )
    return bytes(TS.serialize_cdr(t[DIAG](header=header, status=status), DIAG))


class Sample:
    """What a generated bag holds: per topic the log times and the values the oracle uses."""

    def __init__(self, seed: int, n: int = 3000) -> None:
        rng = np.random.default_rng(seed)
        self.imu_times = START + np.cumsum(rng.integers(1, 20_000_000, n))
        self.z = np.cumsum(rng.normal(0, 1, n))  # a random walk: long runs either side of 0
        self.broken = set(rng.choice(n, 5, replace=False).tolist())  # truncated payloads
        m = n // 10
        self.diag_times = START + np.cumsum(rng.integers(1, 200_000_000, m))
        self.levels = [rng.integers(0, 4, int(rng.integers(0, 4))).tolist() for _ in range(m)]

    def imu_payloads(self) -> list[bytes]:
        payloads = [_imu(float(z), i) for i, z in enumerate(self.z)]
        return [p[:30] if i in self.broken else p for i, p in enumerate(payloads)]

    def write_mcap(self, path: Path) -> Path:
        with BagWriter(path, chunk_size=8192) as bag:
            bag.add_topic(TopicInfo("/imu", IMU))
            bag.add_topic(TopicInfo("/diagnostics", DIAG))
            for t, data in zip(self.imu_times.tolist(), self.imu_payloads(), strict=True):
                bag.write("/imu", data, log_time=t)
            for t, levels in zip(self.diag_times.tolist(), self.levels, strict=True):
                bag.write("/diagnostics", _diagnostics(levels), log_time=t)
        return path

    def write_db3(self, path: Path) -> Path:
        db = sqlite3.connect(path)
        db.executescript(DB3_SCHEMA)
        db.executemany(
            "INSERT INTO topics VALUES (?, ?, ?, 'cdr', '', '')",
            [(1, "/imu", IMU), (2, "/diagnostics", DIAG)],
        )
        imu = zip(self.imu_times.tolist(), self.imu_payloads(), strict=True)
        diagnostics = zip(self.diag_times.tolist(), self.levels, strict=True)
        rows = [(1, t, d) for t, d in imu] + [(2, t, _diagnostics(lv)) for t, lv in diagnostics]
        db.executemany("INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)", rows)
        db.commit()
        db.close()
        return path


@pytest.fixture(scope="module")
def sample() -> Sample:
    return Sample(seed=3)


@pytest.fixture(scope="module", params=["mcap", "db3"])
def sample_bag(
    request: pytest.FixtureRequest, sample: Sample, tmp_path_factory: pytest.TempPathFactory
) -> Path:
    folder = tmp_path_factory.mktemp("episodes")
    if request.param == "mcap":
        return sample.write_mcap(folder / "bag")
    return sample.write_db3(folder / "bag.db3")


@pytest.mark.parametrize("gap_s", [0, 0.05, 0.5])
def test_bulk_path_on_a_fixed_layout_topic(sample_bag: Path, sample: Sample, gap_s: float) -> None:
    gap_ns = int(gap_s * 1e9)
    ok = np.array([i not in sample.broken for i in range(len(sample.z))])
    expected = oracle(sample.imu_times, (sample.z < 0) & ok, gap_ns)
    trigger = parse_topic_condition("imu: linear_acceleration.z < 0")
    with BagReader(sample_bag) as bag:
        found = find_episodes(bag, trigger, gap_ns)
    assert as_tuples(found.episodes) == expected and len(expected) > 5
    assert found.messages == len(sample.z)
    assert found.undecodable == len(sample.broken)
    assert any("5 messages could not be decoded" in p for p in found.problems)


def test_decoded_path_on_a_sequence_condition(sample_bag: Path, sample: Sample) -> None:
    matched = np.array([any(level >= 2 for level in lv) for lv in sample.levels])
    with BagReader(sample_bag) as bag:
        found = find_episodes(bag, parse_topic_condition("/diagnostics: status[*].level >= 2"))
        window_start = int(sample.diag_times[len(sample.diag_times) // 2])
        half = match_topic(
            bag, "/diagnostics", parse_condition("status[*].level >= 2"), Window(window_start)
        )
    assert as_tuples(found.episodes) == oracle(sample.diag_times, matched, 0)
    assert found.undecodable == 0
    later = sample.diag_times >= window_start
    assert half.log_times.tolist() == sample.diag_times[later].tolist()
    assert half.matched.tolist() == matched[later].tolist()


def test_bad_conditions_are_one_clear_error(sample_bag: Path) -> None:
    with BagReader(sample_bag) as bag:
        with pytest.raises(UnknownFieldError, match=r"linear_accel\.z"):
            find_episodes(bag, parse_topic_condition("/imu: linear_accel.z < 0"))
        with pytest.raises(SelectionError, match="cannot compare"):
            find_episodes(bag, parse_topic_condition("/imu: linear_acceleration.z == 'up'"))
        with pytest.raises(SelectionError, match="cannot compare"):
            find_episodes(bag, parse_topic_condition("/diagnostics: status[*].name > 2"))
    for text in ("no colon here", ": x > 1", "/a b: x > 1", "/imu: x >"):
        with pytest.raises(SelectionError):
            parse_topic_condition(text)
