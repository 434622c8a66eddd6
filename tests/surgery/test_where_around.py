"""filter --where (content of a topic) and filter --around (one bag per episode), through the
CLI; outputs read back by rosbags, expectations from the values the test wrote."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from ros2_messages import IMU, STRING, TYPESTORE, qos_yaml, string_cdr
from surgery_samples import START, rosbags_messages, run, run_here

from bagkit.bag import BagWriter, TopicInfo

LATCHED = qos_yaml(depth=1, reliability="reliable", durability="transient_local")
Written = tuple[str, int, bytes]


def imu_with_z(z: float) -> bytes:
    t = TYPESTORE.types
    vec = t["geometry_msgs/msg/Vector3"]
    msg = t[IMU](
        header=t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="imu"
        ),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=vec(x=0.0, y=0.0, z=0.0),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=vec(x=0.0, y=0.0, z=z),
        linear_acceleration_covariance=np.zeros(9),
    )
    return bytes(TYPESTORE.serialize_cdr(msg, IMU))


class Flight:
    """/imu/data every 10 ms with z from a random walk, /text every 25th, /map
    (transient-local) every 400th; the z values kept for the oracle."""

    def __init__(self, path: Path, n: int = 3000) -> None:
        rng = np.random.default_rng(11)
        self.path = path
        self.z = np.cumsum(rng.normal(0, 0.5, n)) + 2.0
        self.times = START + np.arange(n, dtype=np.int64) * 10_000_000
        self.written: list[Written] = []
        with BagWriter(path, chunk_size=8192) as bag:
            bag.add_topic(TopicInfo("/imu/data", IMU))
            bag.add_topic(TopicInfo("/text", STRING))
            bag.add_topic(TopicInfo("/map", STRING, offered_qos_profiles=LATCHED))
            for i, (t, z) in enumerate(zip(self.times.tolist(), self.z.tolist(), strict=True)):
                self._put(bag, "/imu/data", t, imu_with_z(z))
                if i % 25 == 0:
                    self._put(bag, "/text", t + 1, string_cdr(f"text {i}"))
                if i % 400 == 3:
                    self._put(bag, "/map", t + 2, string_cdr(f"map {i}"))

    def _put(self, bag: BagWriter, topic: str, t: int, data: bytes) -> None:
        bag.write(topic, data, log_time=t)
        self.written.append((topic, t, data))

    def episodes(self, gap_ns: int) -> list[tuple[int, int, int]]:
        """Runs of z < 0 merged when closer than gap_ns: a plain loop."""
        found: list[list[int]] = []
        previous = False
        for t, z in zip(self.times.tolist(), self.z.tolist(), strict=True):
            if z < 0:
                if previous or (found and t - found[-1][1] < gap_ns):
                    found[-1][1] = t
                    found[-1][2] += 1
                else:
                    found.append([t, t, 1])
            previous = z < 0
        return [(a, b, c) for a, b, c in found]


@pytest.fixture(scope="module")
def flight(tmp_path_factory: pytest.TempPathFactory) -> Flight:
    return Flight(tmp_path_factory.mktemp("flight") / "flight")


def test_where_keeps_matching_messages_of_the_topics_with_the_fields(
    flight: Flight, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    result = run("filter", str(flight.path), "-o", str(out), "--where", "linear_acceleration.z < 0")
    assert result.returncode == 0, result.stderr
    below = {t for t, z in zip(flight.times.tolist(), flight.z.tolist(), strict=True) if z < 0}
    assert 50 < len(below) < len(flight.z) - 50  # the case keeps some, drops some
    expected = [w for w in flight.written if w[0] != "/imu/data" or w[1] in below]
    assert rosbags_messages(out) == expected
    only_text = tmp_path / "text"
    result = run_here(
        "filter", str(flight.path), "-o", str(only_text), "--topics", "/text",
        "--where", "data == 'text 50'",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert [d for _, _, d in rosbags_messages(only_text)] == [string_cdr("text 50")]


def test_where_naming_a_topic_filters_that_topic_alone(flight: Flight, tmp_path: Path) -> None:
    # /text and /map are both strings: the condition alone would filter both.
    out = tmp_path / "out"
    where = "/text: data == 'text 50'"
    result = run_here("filter", str(flight.path), "-o", str(out), "--where", where)
    assert result.returncode == 0, result.stderr
    expected = [w for w in flight.written if w[0] != "/text" or w[2] == string_cdr("text 50")]
    assert len(expected) == len(flight.written) - len(flight.z) // 25 + 1
    assert rosbags_messages(out) == expected
    converted = tmp_path / "converted"
    result = run_here("convert", str(flight.path), "-o", str(converted), "--where", where)
    assert result.returncode == 0, result.stderr
    assert rosbags_messages(converted) == expected
    # Commands whose --where is the condition alone say how to name the topic.
    echo = run_here("echo", str(flight.path), "/text", "--where", where)
    assert echo.returncode == 2
    assert "(--where \"data == 'text 50'\")" in echo.stderr, echo.stderr


@pytest.mark.parametrize("gap", ["0", "2"])
def test_around_writes_one_bag_per_episode_with_its_latched_state(
    flight: Flight, tmp_path: Path, gap: str
) -> None:
    out = tmp_path / "cuts"
    result = run_here(
        "filter", str(flight.path), "-o", str(out), "--around",
        "imu/data: linear_acceleration.z < 0", "--before", "1", "--after", "500ms",
        "--gap", gap, "--format", "json",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    # Episodes whose windows (1 s before, 500 ms after) would overlap are one.
    episodes = flight.episodes(max(int(float(gap) * 1e9), 1_500_000_001))
    assert len(episodes) > 1
    if gap == "0":  # the case has episodes that close together: fewer cuts than episodes
        assert len(episodes) < len(flight.episodes(0))
    report = json.loads(result.stdout)
    assert [
        (r["episode"]["start_ns"], r["episode"]["end_ns"], r["episode"]["count"]) for r in report
    ] == episodes
    assert sorted(p.name for p in out.iterdir()) == sorted(
        f"flight_{n}" for n in range(len(episodes))
    )
    for n, (first, last, _) in enumerate(episodes):
        start, end = max(first - 1_000_000_000, START), last + 500_000_000 + 1
        window = [w for w in flight.written if start <= w[1] < end]
        latched = [w for w in flight.written if w[0] == "/map" and w[1] < start][-1:]
        expected = [(t, start, d) for t, _, d in latched] + window
        assert rosbags_messages(out / f"flight_{n}") == expected, n
    # No message of the bag is in two of the cuts.
    cut = [w for n in range(len(episodes)) for w in rosbags_messages(out / f"flight_{n}")]
    imu = [w for w in cut if w[0] == "/imu/data"]
    assert len(imu) == len(set(imu))


def test_around_and_where_bad_input(flight: Flight, tmp_path: Path) -> None:
    cases = [
        (["--around", "no colon"], 2, "TOPIC: CONDITION"),
        (["--around", "/imu/data: linear_acceleration.z < -1000"], 1, "holds for no message"),
        (["--around", "/imu/data: z < 0"], 2, "z"),
        (["--around", "/imu/data: linear_acceleration.z < 0", "--start", "1"], 2, "--start"),
        (["--where", "nothing.here > 1"], 2, "nothing.here"),
        (["--where", "__import__('os').system('true')"], 2, "bad condition"),
        (["--where", "linear_acceleration.z == 'up'"], 2, "cannot compare"),
        (["--where", "/nothing: linear_acceleration.z < 0"], 2, "/nothing"),
        (["--where", "/text: linear_acceleration.z < 0"], 2, "linear_acceleration.z"),
        (["--where", "/text: data =="], 2, "expected a value"),  # the condition's own error
    ]
    for args, code, text in cases:
        result = run_here("filter", str(flight.path), "-o", str(tmp_path / "x"), *args)
        assert result.returncode == code, (args, result.stderr)
        lines = result.stderr.strip().splitlines()
        assert lines[-1].startswith("error:") and text in result.stderr, (args, result.stderr)
        assert "Traceback" not in result.stderr
