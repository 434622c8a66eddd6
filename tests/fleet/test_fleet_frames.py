"""``bagkit.fleet.dataframe``: a lazy Dask DataFrame, one partition per bag, whose compute()
on the cluster equals ``bagkit.read_dataframe`` of each bag concatenated."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from distributed import Client

from bagkit.data import read_dataframe
from bagkit.fleet import dataframe
from bagkit.selection.query import Query

FIELDS = ["linear_acceleration.z", "angular_velocity.x"]


def test_compute_equals_read_dataframe_concatenated(client: Client, fleet_bags: list[Path]) -> None:
    frame = dataframe(fleet_bags, "/imu/data", FIELDS)
    assert frame.npartitions == len(fleet_bags)
    expected = pd.concat([read_dataframe(bag, "/imu/data", fields=FIELDS) for bag in fleet_bags])
    got = frame.compute()
    pd.testing.assert_frame_equal(got, expected)
    assert len(got) == sum(400 + 50 * i for i in range(6))


def test_reductions_run_on_the_cluster(client: Client, fleet_bags: list[Path]) -> None:
    frame = dataframe(fleet_bags, "/imu/data", FIELDS)
    expected = pd.concat([read_dataframe(bag, "/imu/data", fields=FIELDS) for bag in fleet_bags])
    column = FIELDS[1]
    assert frame[column].max().compute() == expected[column].max()
    assert frame[column].mean().compute() == pytest.approx(expected[column].mean(), rel=1e-12)


def test_a_query_selects_fields_window_and_messages_in_every_partition(
    client: Client, fleet_bags: list[Path]
) -> None:
    """A query (window relative to each bag's start, a condition) is each bag's read_dataframe
    of that query, concatenated; the same as the keywords."""
    query = Query.create(
        "/imu/data", FIELDS, start="1", end="3", where="linear_acceleration.z > 9.81"
    )
    got = dataframe(fleet_bags, "/imu/data", query=query).compute()
    parts = []
    for bag in fleet_bags:
        whole = read_dataframe(bag, "/imu/data", fields=FIELDS)
        first = whole.index[0]
        inside = whole[
            (whole.index >= first + pd.Timedelta(seconds=1))
            & (whole.index < first + pd.Timedelta(seconds=3))
            & (whole["linear_acceleration.z"] > 9.81)
        ]
        parts.append(inside)
    expected = pd.concat(parts)
    assert 0 < len(got) < sum(len(read_dataframe(b, "/imu/data")) for b in fleet_bags)
    pd.testing.assert_frame_equal(got, expected)
    with pytest.raises(TypeError):
        dataframe(fleet_bags, "/imu/data", FIELDS, query=query)


def test_a_bag_without_the_topic_is_an_empty_partition(
    client: Client, fleet_bags: list[Path], tmp_path: Path
) -> None:
    """As every fleet command reads a topic that some bags lack (stats summary counts the
    others): that bag's partition is empty, first or not; only a topic no bag has is an error."""
    from bagkit.bag import BagWriter, TopicInfo
    from bagkit.selection.errors import UnknownTopicError

    other = tmp_path / "a_other"
    with BagWriter(other) as bag:
        bag.add_topic(TopicInfo("/temperature", "sensor_msgs/msg/Temperature"))
    bags = [other, *fleet_bags, other]
    got = dataframe(bags, "/imu/data", FIELDS).compute()
    expected = pd.concat([read_dataframe(bag, "/imu/data", fields=FIELDS) for bag in fleet_bags])
    pd.testing.assert_frame_equal(got, expected)
    with pytest.raises(UnknownTopicError, match="/imu/dat not in"):
        dataframe(bags, "/imu/dat", FIELDS)
