"""Flattening messages into leaf paths, and the same paths from the schema alone."""

from __future__ import annotations

import numpy as np
import pytest
from random_messages import JAZZY, flat_equal, random_message, same
from reference_flatten import reference_flatten

from bagkit.decode import field_getter, flatten_message, leaf_fields


def test_flatten_paths_and_values() -> None:
    ts = JAZZY
    status = ts.types["diagnostic_msgs/msg/DiagnosticStatus"]
    key_value = ts.types["diagnostic_msgs/msg/KeyValue"]
    msg = ts.types["diagnostic_msgs/msg/DiagnosticArray"](
        header=ts.types["std_msgs/msg/Header"](
            stamp=ts.types["builtin_interfaces/msg/Time"](sec=3, nanosec=4), frame_id="base"
        ),
        status=[
            status(level=2, name="a", message="m", hardware_id="h", values=[key_value("k", "v")]),
            status(level=0, name="b", message="", hardware_id="", values=[]),
        ],
    )
    flat = flatten_message(msg, ts)
    assert flat == {
        "header.stamp.sec": 3,
        "header.stamp.nanosec": 4,
        "header.frame_id": "base",
        "status[].level": [2, 0],
        "status[].name": ["a", "b"],
        "status[].message": ["m", ""],
        "status[].hardware_id": ["h", ""],
        "status[].values[].key": ["k"],
        "status[].values[].value": ["v"],
    }
    assert [leaf.path for leaf in leaf_fields(ts, msg.__msgtype__)] == list(flat)
    numeric = flatten_message(msg, ts, numeric_only=True)
    assert numeric == {"header.stamp.sec": 3, "header.stamp.nanosec": 4, "status[].level": [2, 0]}

    flag = flatten_message(ts.types["std_msgs/msg/Bool"](data=True), ts)
    assert flag == {"data": 1} and isinstance(flag["data"], int)
    imu = random_message(ts, "sensor_msgs/msg/Imu", np.random.default_rng(3))
    flat_imu = flatten_message(imu, ts)
    assert same(flat_imu["orientation_covariance[8]"], imu.orientation_covariance[8])  # type: ignore[attr-defined]
    assert len(flat_imu) == 3 + 4 + 9 + 3 + 9 + 3 + 9


def test_generated_flattener_equals_a_plain_recursive_walk() -> None:
    """Every Jazzy type rosbags ships, with random values, sequence lengths and strings."""
    rng = np.random.default_rng(11)
    for typename in sorted(JAZZY.fielddefs):
        for _ in range(3):
            msg = random_message(JAZZY, typename, rng)
            for numeric_only in (False, True):
                ours = flatten_message(msg, JAZZY, numeric_only=numeric_only)
                reference = reference_flatten(msg, JAZZY, numeric_only=numeric_only)
                assert list(ours) == list(reference), typename
                for path, value in ours.items():
                    assert flat_equal(value, reference[path]), (typename, path)


@pytest.mark.parametrize(
    "typename",
    ["sensor_msgs/msg/Imu", "nav_msgs/msg/Odometry", "diagnostic_msgs/msg/DiagnosticArray"],
)
def test_field_getter_returns_the_flattened_values_of_its_paths(typename: str) -> None:
    rng = np.random.default_rng(12)
    paths = [leaf.path for leaf in leaf_fields(JAZZY, typename)]
    selections = [
        tuple(paths),  # whole arrays in order: read with one unpacking
        tuple(p for p in paths if not p.endswith(("[3]", "[7]"))),  # arrays with holes
        tuple(rng.permutation(paths)[: len(paths) // 2]),
    ]
    for selection in selections:
        get = field_getter(JAZZY, typename, selection)
        for _ in range(5):
            msg = random_message(JAZZY, typename, rng)
            flat = flatten_message(msg, JAZZY)
            values = get(msg)
            assert len(values) == len(selection)
            for path, value in zip(selection, values, strict=True):
                assert flat_equal(value, flat[path]), (typename, path)
