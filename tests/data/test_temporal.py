"""Temporal conditions on synthetic bags: each case's expected intervals come from how the
bag was built (which messages were left out, frozen, NaN), not from bagkit's output."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from bagkit_runs import bagkit_in_process
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagReader, BagWriter, TopicInfo
from bagkit.data.episodes import find_episodes
from bagkit.selection.conditions import parse_condition, parse_topic_condition
from bagkit.selection.errors import SelectionError

TS = get_typestore(Stores.ROS2_JAZZY)
IMU = "sensor_msgs/msg/Imu"
STRING = "std_msgs/msg/String"
START = 1_700_000_000_000_000_000
MS = 1_000_000
PERIOD = 10 * MS  # 100 Hz
N = 1000  # 10 s
SILENT = range(300, 400)  # no message from 3.00 s to 3.99 s
FROZEN = range(600, 851)  # z stays 5.0 from 6.00 s to 8.50 s
NAN_AT = 900  # z is NaN at 9.00 s
JUMP_AT = 950  # z jumps by 1000 at 9.50 s
LATE = range(700, 720)  # header stamps 300 ms behind the log time


def t(i: int) -> int:
    return START + i * PERIOD


def z_of(i: int) -> float:
    if i in FROZEN:
        return 5.0
    if i == NAN_AT:
        return float("nan")
    return float(i % 7) + (1000.0 if i >= JUMP_AT else 0.0)


def _imu(i: int) -> bytes:
    types = TS.types
    vec = types["geometry_msgs/msg/Vector3"]
    stamp = t(i) - (300 * MS if i in LATE else 0)
    msg = types[IMU](
        header=types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](sec=stamp // 10**9, nanosec=stamp % 10**9),
            frame_id="imu",
        ),
        orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=vec(x=0.0, y=0.0, z=0.0),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=vec(x=0.0, y=0.0, z=z_of(i)),
        linear_acceleration_covariance=np.zeros(9),
    )
    return bytes(TS.serialize_cdr(msg, IMU))


def _text(value: str) -> bytes:
    return bytes(TS.serialize_cdr(TS.types[STRING](data=value), STRING))


LATCHED = "- history: keep_last\n  depth: 1\n  durability: transient_local\n"
# /alerts publishes on change: ERROR at 12.0 s (bag time 2.0 s) until OK at 14.0 s (4.0 s).
ALERTS = [(0, "OK"), (200, "ERROR"), (400, "OK"), (700, "ERROR"), (750, "OK")]


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("temporal") / "bag"
    with BagWriter(path, chunk_size=16384) as writer:
        writer.add_topic(TopicInfo("/imu", IMU))
        writer.add_topic(TopicInfo("/alerts", STRING, offered_qos_profiles=LATCHED))
        writer.add_topic(TopicInfo("/events", STRING))
        for i in range(N):
            if i not in SILENT:
                writer.write("/imu", _imu(i), log_time=t(i))
        for i, value in ALERTS:
            writer.write("/alerts", _text(value), log_time=t(i))
            writer.write("/events", _text(value), log_time=t(i))
    return path


LAST = t(N - 1)
# (condition, expected episodes (start, end) from the construction above).
CASES = [
    # The silence: from the last message before it (2.99 s) to the first after (4.00 s).
    ("/imu: gap > 500ms", [(t(299), t(400))]),
    ("/imu: gap > 2s", []),
    # rate: windows (t - 1 s, t] holding < 50 messages, as [t - 1 s, t]. The last message
    # before the silence is 299; a window holds < 50 once it starts past 2.50 s (t >= 3.50 s)
    # and until 50 messages after 4.00 s are in it (t = 4.49 s).
    ("/imu: rate < 50 Hz over 1s", [(t(250), t(449) - 1)]),
    ("/imu: unchanged(linear_acceleration.z) for 2s", [(t(600), t(850))]),
    ("/imu: unchanged(linear_acceleration.z) for 3s", []),
    ("/imu: isnan(*)", [(t(NAN_AT), t(NAN_AT))]),
    ("/imu: isnan(linear_acceleration.z)", [(t(NAN_AT), t(NAN_AT))]),
    ("/imu: isinf(*)", []),
    ("/imu: delta(linear_acceleration.z) > 100", [(t(JUMP_AT), t(JUMP_AT))]),
    ("/imu: age(header.stamp) > 200ms", [(t(LATE[0]), t(LATE[-1]))]),
    ("/imu: age(header.stamp) > 200ms for 100ms", [(t(LATE[0]), t(LATE[-1]))]),
    ("/imu: age(header.stamp) > 200ms for 1s", []),
    ("/imu: gap > 500ms or isnan(*)", [(t(299), t(400)), (t(NAN_AT), t(NAN_AT))]),
    ("/imu: not gap > 500ms", [(t(0), t(299) - 1), (t(400) + 1, LAST)]),
    (
        "/imu: unchanged(linear_acceleration.z) for 2s and age(header.stamp) > 200ms",
        [(t(LATE[0]), t(LATE[-1]))],
    ),
    # A state topic (latched): ERROR holds until the next message, 2.0 s then 0.5 s.
    ("/alerts: data == 'ERROR'", [(t(200), t(400)), (t(700), t(750))]),
    ("/alerts: data == 'ERROR' for 1s", [(t(200), t(400))]),
    # The same messages on a topic that is not a state topic: instants.
    ("/events: data == 'ERROR'", [(t(200), t(200)), (t(700), t(700))]),
]


@pytest.mark.parametrize(("when", "expected"), CASES, ids=[c[0] for c in CASES])
def test_temporal_episodes_are_those_of_the_construction(
    bag: Path, when: str, expected: list[tuple[int, int]]
) -> None:
    with BagReader(bag) as reader:
        found = find_episodes(reader, parse_topic_condition(when))
    assert [(start, end) for start, end, _ in found.spans.tolist()] == expected


def test_the_gap_at_the_end_of_the_bag(tmp_path: Path) -> None:
    path = tmp_path / "bag"
    with BagWriter(path) as writer:
        writer.add_topic(TopicInfo("/imu", IMU))
        writer.add_topic(TopicInfo("/alerts", STRING))
        for i in range(100):
            writer.write("/imu", _imu(i), log_time=t(i))
        writer.write("/alerts", _text("late"), log_time=t(300))  # the bag ends at 3 s
    with BagReader(path) as reader:
        found = find_episodes(reader, parse_topic_condition("/imu: gap > 1s"))
    assert found.spans.tolist() == [[t(99), t(300), 1]]


def bagkit(*args: str) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` in this process (tests/bagkit_runs.py)."""
    return bagkit_in_process(list(args))


def test_find_cli_with_a_temporal_condition(bag: Path) -> None:
    result = bagkit("find", str(bag), "--when", "/imu: gap > 500ms", "--format", "json")
    assert result.returncode == 0, result.stderr
    episodes = json.loads(result.stdout)
    assert [(e["start_ns"], e["end_ns"], e["count"]) for e in episodes] == [(t(299), t(400), 2)]


def test_filter_around_a_temporal_condition(bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "cuts"
    result = bagkit(
        "filter",
        str(bag),
        "-o",
        str(out),
        "--around",
        "/imu: unchanged(linear_acceleration.z) for 2s",
        "--before",
        "0",
        "--after",
        "0",
    )
    assert result.returncode == 0, result.stderr
    cuts = sorted(p for p in out.iterdir() if p.is_dir())
    assert len(cuts) == 1
    with BagReader(cuts[0]) as reader:
        times = [m.log_time for m in reader.messages(["/imu"])]
    assert times == [t(i) for i in FROZEN]


@pytest.mark.parametrize(
    ("when", "words"),
    [
        ("/imu: gap > 5 Hz", "gap takes a duration"),
        ("/imu: rate < 5 s over 1s", "rate takes a frequency"),
        ("/imu: frozen(linear_acceleration.z) for 2s", "unknown function 'frozen'"),
        ("/imu: unchanged(nope) for 2s", "nope"),
    ],
)
def test_bad_temporal_conditions_are_one_error(bag: Path, when: str, words: str) -> None:
    result = bagkit("find", str(bag), "--when", when)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and words in lines[0], lines


def test_a_term_over_time_on_a_sequence_is_one_error_saying_so() -> None:
    # status[] of /alerts (diagnostic_msgs/msg/DiagnosticArray) may change length.
    golden = Path(__file__).parents[2] / "fixtures" / "nominal" / "golden"
    result = bagkit("find", str(golden), "--when", "/alerts: delta(status[*].level) > 0")
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "status[*].level of /alerts is in a sequence" in lines[0], lines


def test_echo_where_over_time_prints_the_messages_of_the_episodes(bag: Path) -> None:
    result = bagkit("echo", str(bag), "/imu", "--where", "gap > 500ms", "--format", "json")
    assert result.returncode == 0, result.stderr
    lines = [json.loads(line) for line in result.stdout.splitlines()]
    assert [line["log_time"] for line in lines] == [t(299), t(400)]  # around the silence


def test_filter_where_over_time_keeps_the_messages_inside(bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "frozen"
    when = "unchanged(linear_acceleration.z) for 2s or isnan(*)"
    result = bagkit("filter", str(bag), "-o", str(out), "--topics", "/imu", "--where", when)
    assert result.returncode == 0, result.stderr
    with BagReader(out) as reader:
        times = [m.log_time for m in reader.messages(["/imu"])]
    assert times == [t(i) for i in [*FROZEN, NAN_AT]]


def test_stats_where_refuses_a_temporal_condition_with_one_error(bag: Path) -> None:
    result = bagkit("stats", "summary", str(bag), "--where", "gap > 1s")
    assert result.returncode == 2
    assert result.stderr.startswith("error: --where 'gap > 1s' checks each message alone")
    assert len(result.stderr.strip().splitlines()) == 1
    with pytest.raises(SelectionError) as raised:  # the library names its own field
        parse_condition("gap > 1s").require_per_message()
    assert raised.value.field == "where" and str(raised.value).startswith("where: 'gap > 1s'")


@pytest.mark.parametrize("storage", ["mcap", "db3"])
def test_gaps_from_indexes_and_from_messages_equal_a_loop(storage: str, tmp_path: Path) -> None:
    """MCAP's gaps come from its Message Index records, .db3's from its rows: both equal a
    plain loop over the log times the test wrote."""
    sys.path.insert(0, str(Path(__file__).parent))
    from test_episodes import Sample

    sample = Sample(seed=5)
    path = sample.write_mcap(tmp_path / "bag") if storage == "mcap" else None
    path = path or sample.write_db3(tmp_path / "bag.db3")
    times = sample.imu_times.tolist()
    end = max(times[-1], int(sample.diag_times[-1]))
    expected: list[list[int]] = []
    for before, after in [*itertools.pairwise(times), (times[-1], end)]:
        if after - before > 15 * MS:
            if expected and expected[-1][1] == before:  # silences sharing a message: one
                expected[-1][1] = after
            else:
                expected.append([before, after])
    assert len(expected) > 10
    with BagReader(path) as reader:
        indexed = reader.index_log_times("/imu")
        assert (indexed is None) == (storage == "db3")
        found = find_episodes(reader, parse_topic_condition("/imu: gap > 15ms"))
    assert [[a, b] for a, b, _ in found.spans.tolist()] == expected


def test_a_topic_declared_a_state_topic(bag: Path) -> None:
    """/events holds what /alerts holds, recorded volatile: instants, unless declared."""
    when = "/events: data == 'ERROR'"
    plain = bagkit("find", str(bag), "--when", when, "--format", "json")
    declared = bagkit(
        "find", str(bag), "--when", when, "--state-topics", "events", "--format", "json"
    )
    assert plain.returncode == declared.returncode == 0, plain.stderr + declared.stderr
    spans = [
        [(e["start_ns"], e["end_ns"]) for e in json.loads(r.stdout)] for r in (plain, declared)
    ]
    assert spans == [
        [(t(200), t(200)), (t(700), t(700))],
        [(t(200), t(400)), (t(700), t(750))],  # ERROR until the next message (OK)
    ]


def test_latency_between_two_topics_of_a_bag(tmp_path: Path) -> None:
    """/out carries /imu's stamp, logged 30 ms after it, 80 ms for messages 40..49 (10 Hz:
    the outputs keep their order)."""
    path = tmp_path / "bag"
    slow = range(40, 50)

    def logged(i: int) -> int:
        return START + i * 100 * MS

    with BagWriter(path) as writer:
        writer.add_topic(TopicInfo("/imu", IMU))
        writer.add_topic(TopicInfo("/out", IMU))
        for i in range(100):
            writer.write("/imu", _imu(i), log_time=logged(i))
            delay = 80 * MS if i in slow else 30 * MS
            writer.write("/out", _imu(i), log_time=logged(i) + delay)  # /imu's stamp
    when = "/out: latency(/imu -> /out, header.stamp) > 50ms"
    with BagReader(path) as reader:
        found = find_episodes(reader, parse_topic_condition(when))
    assert found.spans.tolist() == [[logged(40) + 80 * MS, logged(49) + 80 * MS, 10]]
    wrong = bagkit("find", str(path), "--when", "/imu: latency(/imu -> /out, header.stamp) > 5ms")
    assert wrong.returncode == 2 and "a condition on /out" in wrong.stderr
