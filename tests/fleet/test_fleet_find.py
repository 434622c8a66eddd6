"""``bagkit find``: episodes over many bags equal an oracle's, on Dask as in one process.

The oracle reads every Imu payload with the mcap library, decodes it with rosbags, and walks
the messages in a plain Python loop: consecutive matching messages are one episode, and a
match less than ``gap`` after the last one (messages that do not match between them) joins
it.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pandas as pd
import pytest
from bagkit_runs import bagkit_in_process, bagkit_subprocess
from distributed import Client
from fleet_bags import IMU, STORE
from mcap.reader import make_reader

from bagkit.fleet.errors import FleetError
from bagkit.fleet.events import parse_events
from bagkit.fleet.find import FoundEpisode, find_fleet
from bagkit.selection.errors import SelectionError, UnknownFieldError, UnknownTopicError
from bagkit.selection.query import Query

WHEN = "/imu/data: linear_acceleration.z > 9.85 or angular_velocity.x < -0.03"


def _oracle(bags: list[Path], gap_ns: int) -> list[FoundEpisode]:
    found = []
    for bag in bags:
        rows = []
        starts = []  # each file's first log time, from its statistics: the bag's start
        for file in sorted(bag.glob("*.mcap")):
            with open(file, "rb") as f:
                summary = make_reader(f).get_summary()
                assert summary is not None and summary.statistics is not None
                starts.append(summary.statistics.message_start_time)
            with open(file, "rb") as f:
                for _, _channel, message in make_reader(f).iter_messages(topics=["/imu/data"]):
                    msg = STORE.deserialize_cdr(message.data, IMU)
                    hit = msg.linear_acceleration.z > 9.85 or msg.angular_velocity.x < -0.03
                    rows.append((message.log_time, hit))
        frame = pd.DataFrame(rows, columns=["t", "hit"]).sort_values("t", kind="stable")
        current: list[int] | None = None  # [start, end, count]
        previous_hit = False
        for t, hit in zip(frame["t"].tolist(), frame["hit"].tolist(), strict=True):
            after_hit, previous_hit = previous_hit, hit
            if not hit:
                continue
            if current is not None and (after_hit or t - current[1] < gap_ns):
                current[1], current[2] = t, current[2] + 1
                continue
            if current is not None:
                found.append(FoundEpisode(str(bag), "/imu/data", *current, min(starts)))
            current = [t, t, 1]
        if current is not None:
            found.append(FoundEpisode(str(bag), "/imu/data", *current, min(starts)))
    return found


@pytest.mark.parametrize("gap_ns", [0, 10_000_000, 25_000_000, 200_000_000])
def test_episodes_equal_the_oracle(fleet_bags: list[Path], gap_ns: int) -> None:
    expected = _oracle(fleet_bags, gap_ns)
    assert len(expected) > len(fleet_bags), "the condition must make several episodes"
    result = find_fleet(fleet_bags, when=WHEN, gap_ns=gap_ns)
    assert result.episodes == expected
    assert result.problems == [] and result.unread == 0


def test_dask_gives_what_one_process_gives(fleet_bags: list[Path], client: Client) -> None:
    here = find_fleet(fleet_bags, when=WHEN, gap_ns=20_000_000)
    done: list[int] = []
    there = find_fleet(fleet_bags, when=WHEN, gap_ns=20_000_000, client=client, done=done.append)
    assert there.episodes == here.episodes and there.episodes
    assert sorted(done) == list(range(len(fleet_bags)))


def test_a_window_of_each_bag(fleet_bags: list[Path]) -> None:
    whole = find_fleet(fleet_bags, when=WHEN)
    part = find_fleet(fleet_bags, when=WHEN, query=Query.create(start="1", end="2"))
    assert part.episodes
    for episode in part.episodes:
        assert episode in whole.episodes  # gap 0: windowing cuts no run of one message


def test_bad_input(fleet_bags: list[Path], tmp_path: Path) -> None:
    with pytest.raises(SelectionError, match="expected 'TOPIC: CONDITION'"):
        find_fleet(fleet_bags, when="linear_acceleration.z > 1")
    with pytest.raises(UnknownFieldError, match="no field"):
        find_fleet(fleet_bags, when="/imu/data: status[*].level > 1")
    with pytest.raises(UnknownTopicError, match="topic /nowhere not in any of the bags"):
        find_fleet(fleet_bags, when="/nowhere: x > 1")
    (tmp_path / "broken.mcap").write_bytes(b"not a bag")
    with pytest.raises(FleetError, match="no bag could be read"):
        find_fleet([tmp_path / "broken.mcap"], when=WHEN)
    result = find_fleet([*fleet_bags[:1], tmp_path / "broken.mcap"], when=WHEN)
    assert result.unread == 1 and any("broken.mcap: not read" in p for p in result.problems)
    for specs in (["no name"], [f"a={WHEN}", f"a={WHEN}"]):
        with pytest.raises(SelectionError) as raised:  # the library names its own field
            parse_events(specs)
        assert raised.value.field == "events" and "--events" not in str(raised.value)


def _bagkit(
    *args: str | Path, cwd: Path, process: bool = False
) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` in this process (tests/bagkit_runs.py), or a real one."""
    return (bagkit_subprocess if process else bagkit_in_process)(list(args), cwd)


def test_cli_json_and_parquet_hold_the_episodes(fleet_dir: Path, tmp_path: Path) -> None:
    from bagkit.fleet import expand_bags

    expected = [e.to_dict() for e in _oracle(expand_bags([fleet_dir]), 20_000_000)]
    shown = _bagkit("find", fleet_dir, "--when", WHEN, "--gap", "20ms", "--format", "json",
                    "--workers", "0", cwd=tmp_path)  # fmt: skip
    assert shown.returncode == 0, shown.stderr
    assert json.loads(shown.stdout) == expected
    written = _bagkit("find", fleet_dir, "--when", WHEN, "--gap", "0.02", "-o", "e.parquet",
                      "--workers", "0", cwd=tmp_path)  # fmt: skip
    assert written.returncode == 0, written.stderr
    assert pd.read_parquet(tmp_path / "e.parquet").to_dict("records") == expected
    table = _bagkit("find", fleet_dir, "--when", WHEN, "--workers", "0", cwd=tmp_path)
    assert table.returncode == 0 and "episodes of /imu/data" in table.stdout


@pytest.mark.parametrize(
    ("args", "error"),
    [
        (["--when", "x > 1"], "error: 'x > 1': expected 'TOPIC: CONDITION'"),
        (["--when", "/imu/data: z >"], "error: '/imu/data: z >': bad condition"),
        (["--when", WHEN, "--gap", "-1"], "error: bad --gap"),
        (["--when", WHEN, "--format", "parquet"], "error: --format parquet and -o/--output"),
        (["--when", "/imu/data: __import__('os').system('touch PWNED') == 0"], "error: "),
    ],
)
def test_cli_bad_input_is_one_line(
    fleet_dir: Path, tmp_path: Path, args: list[str], error: str
) -> None:
    # The injection a real process: what it could run would run there.
    injection = "__import__" in args[1]
    result = _bagkit("find", fleet_dir, *args, "--workers", "0", cwd=tmp_path, process=injection)
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith(error) and result.stderr.count("\n") == 1, result.stderr
    assert not (tmp_path / "PWNED").exists()


def test_catalog_events_store_the_episodes_and_search_only_what_changed(
    fleet_dir: Path, tmp_path: Path
) -> None:
    import shutil

    from bagkit.fleet.events import events_path, query_events, read_events

    root = tmp_path / "bags"
    shutil.copytree(fleet_dir, root)
    catalog = tmp_path / "cat.parquet"
    event = f"high={WHEN}"
    built = _bagkit("catalog", root, "-o", catalog, "--events", event, "--workers", "0",
                    cwd=tmp_path)  # fmt: skip
    assert built.returncode == 0, built.stderr
    twice = _bagkit("catalog", root, "-o", catalog, "--events", event, "--events", event,
                    cwd=tmp_path)  # fmt: skip
    assert (twice.returncode, twice.stderr) == (2, "error: --events names 'high' twice\n")
    from bagkit.fleet import expand_bags

    bags = expand_bags([root])
    expected = find_fleet(bags, when=WHEN).episodes
    frame = read_events(events_path(catalog))
    had = query_events(frame, "high")
    assert [(p, int(s.value), int(e.value), c) for p, s, e, c in zip(
        had["path"], had["start"], had["end"], had["count"], strict=True
    )] == [(e.bag, e.start_ns, e.end_ns, e.count) for e in expected]  # fmt: skip
    # A window up to the earliest episode of all: only that bag's (the bags are hours apart).
    first = min(expected, key=lambda e: e.start_ns)
    early = query_events(frame, "high", Query.create(end=f"{first.start_ns}ns"))
    assert set(early["path"]) == {first.bag}

    shutil.rmtree(bags[0])  # a bag gone, the others unchanged: nothing searched again
    again = _bagkit("catalog", root, "-o", catalog, "--events", event, "--workers", "0",
                    cwd=tmp_path)  # fmt: skip
    assert again.returncode == 0, again.stderr
    assert "1 removed" in again.stderr
    left = read_events(events_path(catalog))
    assert str(bags[0]) not in set(left["path"])
    assert len(left) == len(frame[frame["path"] != str(bags[0])])

    listed = _bagkit("catalog", "query", catalog, "--event", "high", "--format", "json",
                     cwd=tmp_path)  # fmt: skip
    assert listed.returncode == 0, listed.stderr
    assert {r["path"] for r in json.loads(listed.stdout)} == {str(b) for b in bags[1:]}
    unknown = _bagkit("catalog", "query", catalog, "--event", "low", cwd=tmp_path)
    assert unknown.returncode == 2 and unknown.stderr.startswith("error: no event 'low'")


def test_stats_where_on_dask_equals_one_process(fleet_bags: list[Path], client: Client) -> None:
    from bagkit.fleet import summarize_fleet
    from bagkit.stats import summarize

    where = "linear_acceleration.z > 9.85 or angular_velocity.x < -0.03"
    query = Query.create("/imu/data", where=where)
    here = summarize(fleet_bags, query)
    there = summarize_fleet(fleet_bags, client=client, query=query)
    matched = sum(e.count for e in find_fleet(fleet_bags, when=WHEN).episodes)
    assert here.topics[0].count == there.topics[0].count == matched
    for mine, theirs in zip(here.topics[0].fields, there.topics[0].fields, strict=True):
        assert (mine.count, mine.min, mine.max) == (theirs.count, theirs.min, theirs.max)
        assert mine.mean == pytest.approx(theirs.mean, rel=1e-12, abs=1e-12)


def test_export_where_over_many_bags_keeps_what_find_matches(
    fleet_dir: Path, tmp_path: Path
) -> None:
    from bagkit.fleet import expand_bags

    where = WHEN.partition(": ")[2]
    done = _bagkit("export", fleet_dir, "-t", "/imu/data", "-o", "out", "--where", where,
                   "--workers", "0", cwd=tmp_path)  # fmt: skip
    assert done.returncode == 0, done.stderr
    bags = expand_bags([fleet_dir])
    rows = sum(len(pd.read_parquet(f)) for f in (tmp_path / "out").rglob("*.parquet"))
    assert rows == sum(e.count for e in find_fleet(bags, when=WHEN).episodes)


def test_messages_that_do_not_decode_are_no_gap_beside_a_field_term(tmp_path: Path) -> None:
    """``gap`` and ``rate`` count every message that arrived: a field term in the same
    condition (which decodes the topic) must not turn messages that do not decode into a
    silence."""
    from bagkit.bag import BagWriter, TopicInfo

    kind = "sensor_msgs/msg/Temperature"
    t = STORE.types
    with BagWriter(tmp_path / "cut") as bag:
        bag.add_topic(TopicInfo("/temp", kind))
        for i in range(30):  # 10 Hz; from 1.0 to 2.0 s payloads cut short
            ns = 1_700_000_000_000_000_000 + i * 100_000_000
            stamp = t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
            header = t["std_msgs/msg/Header"](stamp=stamp, frame_id="t")
            message = t[kind](header=header, temperature=20.0, variance=0.0)
            data = bytes(STORE.serialize_cdr(message, kind))
            bag.write("/temp", data[:10] if 10 <= i < 20 else data, log_time=ns)
    for when in ["gap > 150ms or temperature > 100", "rate < 5 Hz over 1s or temperature > 100"]:
        result = bagkit_subprocess(
            ["find", "cut", "--when", f"/temp: {when}", "--format", "json"], tmp_path
        )
        assert result.returncode == 0, result.stderr
        assert json.loads(result.stdout) == [], when
        assert "/temp: 10 messages could not be decoded" in result.stderr
