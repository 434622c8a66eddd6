"""Fleet statistics on a real 2-worker Dask cluster equal the in-process summary: counts,
min and max exactly, mean and std within 1e-12 relative."""

from __future__ import annotations

import math
import shutil
import threading
from pathlib import Path

import numpy as np
import psutil
import pytest
from distributed import Client
from fleet_bags import worker_pids

from bagkit.fleet import expand_bags, summarize_fleet
from bagkit.selection.query import Query
from bagkit.stats import StatsError, Summary, UnknownTopicError, summarize

REPO = Path(__file__).resolve().parents[2]
RELATIVE = 1e-12


def _close(a: float | None, b: float | None) -> bool:
    if a is None or b is None or not (math.isfinite(a) and math.isfinite(b)):
        return a == b or (a is not None and b is not None and math.isnan(a) and math.isnan(b))
    return abs(a - b) <= RELATIVE * max(abs(a), abs(b)) or a == b


def assert_same(expected: Summary, got: Summary) -> None:
    assert got.bags == expected.bags
    assert (got.start_ns, got.end_ns) == (expected.start_ns, expected.end_ns)
    assert got.skipped == expected.skipped
    assert got.problems == expected.problems
    assert [t.topic for t in got.topics] == [t.topic for t in expected.topics]
    for want, have in zip(expected.topics, got.topics, strict=True):
        assert (have.type, have.count, have.rate_hz) == (want.type, want.count, want.rate_hz)
        for f, g in zip(want.fields, have.fields, strict=True):
            assert (g.field, g.count, g.nan_count, g.min, g.max) == (
                f.field,
                f.count,
                f.nan_count,
                f.min,
                f.max,
            )
            assert _close(f.mean, g.mean), (want.topic, f.field, f.mean, g.mean)
            assert _close(f.std, g.std), (want.topic, f.field, f.std, g.std)


def test_generated_bags_match_in_process(client: Client, fleet_bags: list[Path]) -> None:
    expected = summarize(fleet_bags)
    got = summarize_fleet(fleet_bags, client=client)
    assert_same(expected, got)
    # An oracle that shares no code with either: the fields' spread across bags is large
    # (angular_velocity is centred on 1000 * bag index), which a naive merge gets wrong.
    imu = next(t for t in got.topics if t.topic == "/imu/data")
    count = sum(400 + 50 * i for i in range(6))
    assert imu.count == count
    stamp = next(f for f in imu.fields if f.field == "header.stamp.sec")
    seconds = np.concatenate(
        [
            (1_700_000_000_000_000_000 + i * 3_600 * 10**9 + np.arange(400 + 50 * i) * 10**7)
            // 10**9
            for i in range(6)
        ]
    )
    assert stamp.mean == pytest.approx(seconds.mean(), rel=1e-13)
    assert stamp.std == pytest.approx(seconds.std(ddof=1), rel=1e-12)


def test_selection_and_window_match_in_process(client: Client, fleet_bags: list[Path]) -> None:
    query = Query.create(
        "/imu/data",
        ["linear_acceleration.*", "orientation_covariance[]"],
        start="1",  # seconds into each bag
        end="-0.5",  # before each one's end
    )
    assert_same(
        summarize(fleet_bags, query), summarize_fleet(fleet_bags, client=client, query=query)
    )


def test_golden_fixtures_match_in_process(client: Client) -> None:
    bags = expand_bags([REPO / "fixtures"])
    assert len(bags) >= 3
    assert_same(summarize(bags), summarize_fleet(bags, client=client))


def test_interop_bags_match_in_process(client: Client, interop_dir: Path) -> None:
    bags = expand_bags([interop_dir])
    # The bags that pool in one process: some define a type differently from the bags before
    # them, and the error names that bag.
    pool = list(bags)
    while True:
        try:
            summarize(pool)
            break
        except StatsError as exc:
            named = [bag for bag in pool if str(bag) in str(exc)]
            assert named, exc
            pool = [bag for bag in pool if bag not in named]
    assert len(pool) >= 5
    assert_same(summarize(pool), summarize_fleet(pool, client=client))
    # Those that do not pool fail with the same error.
    with pytest.raises(StatsError) as in_process:
        summarize(bags)
    with pytest.raises(StatsError) as fleet:
        summarize_fleet(bags, client=client)
    assert str(fleet.value) == str(in_process.value)


def test_unknown_topic_is_the_same_error(client: Client, fleet_bags: list[Path]) -> None:
    with pytest.raises(UnknownTopicError) as in_process:
        summarize(fleet_bags, Query.create("/nope"))
    with pytest.raises(UnknownTopicError) as fleet:
        summarize_fleet(fleet_bags, client=client, query=Query.create("/nope"))
    assert str(fleet.value) == str(in_process.value)


def test_unreadable_bag_is_a_problem_and_the_rest_completes(
    client: Client, fleet_bags: list[Path], tmp_path: Path
) -> None:
    broken = tmp_path / "broken.mcap"
    broken.write_bytes(b"\x89MCAP0\r\n" + b"not a bag at all" * 10)
    missing = tmp_path / "missing_bag"
    got = summarize_fleet([*fleet_bags, broken, missing], client=client)
    expected = summarize(fleet_bags)
    assert [t.count for t in got.topics] == [t.count for t in expected.topics]
    assert any(p.startswith(f"{broken}: not read:") for p in got.problems), got.problems
    assert any(p.startswith(f"{missing}: not read:") for p in got.problems), got.problems


def test_a_killed_worker_does_not_change_the_result(
    client: Client, fleet_bags: list[Path], tmp_path: Path
) -> None:
    # 24 tasks: copies of the bags, so that tasks are still running when a worker is killed.
    bags = []
    for copy in range(4):
        for bag in fleet_bags:
            bags.append(shutil.copytree(bag, tmp_path / f"{copy}_{bag.name}"))
    expected = summarize(bags)
    client.wait_for_workers(2)
    victim = next(iter(worker_pids(client).values()))
    killed = threading.Event()

    def kill_after_first(index: int) -> None:
        if not killed.is_set():
            psutil.Process(victim).kill()
            killed.set()

    got = summarize_fleet(bags, client=client, done=kill_after_first)
    assert killed.is_set()
    assert not psutil.pid_exists(victim) or psutil.Process(victim).status() == psutil.STATUS_ZOMBIE
    assert victim not in worker_pids(client).values()
    assert_same(expected, got)
    client.wait_for_workers(2)  # the nanny restarts it: the next tests have two workers again


def test_a_service_name_is_resolved_in_each_bag_as_in_process(
    client: Client, fleet_bags: list[Path], interop_dir: Path
) -> None:
    """``-t /service`` summarizes the service's event topic of the bags that recorded it, on the
    workers as in one process; a misspelt one names the closest service."""
    services = interop_dir / "rosbag2_tests/resources/mcap/bag_with_topics_and_service_events"
    bags = [services, fleet_bags[0]]
    query = Query.create("/test_service1")
    fleet = summarize_fleet(bags, client=client, query=query)
    assert [t.topic for t in fleet.topics] == ["/test_service1/_service_event"]
    assert fleet.topics[0].count > 0
    assert_same(summarize(bags, query), fleet)
    with pytest.raises(UnknownTopicError, match="/test_servce1 not in any of the bags") as err:
        summarize_fleet(bags, client=client, query=Query.create("/test_servce1"))
    assert "/test_service1" in str(err.value)
