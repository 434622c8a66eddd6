"""Test bags written with rosbags' writer and serializer: the oracle shares no code with bagkit.

Each generator returns the messages to write and, per numeric leaf field, the values it put in
them (as numpy arrays), so that expected statistics come from the generator, never from a decode.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
T0 = 1_700_000_000_000_000_000
FRAMES = ["imu", "imu_link", "", "a_rather_long_frame_name_x"]
# Statistics equal numpy on the written values within this (relative) tolerance.
RTOL = 1e-9


@dataclass
class TopicData:
    """What a test wrote on one topic: type, (log_time, message) pairs, values per leaf field."""

    type: str
    messages: list[tuple[int, object]] = field(default_factory=list)
    values: dict[str, list[float]] = field(default_factory=dict)

    def add(self, log_time: int, msg: object, values: dict[str, list[float] | float]) -> None:
        self.messages.append((log_time, msg))
        for path, value in values.items():
            self.values.setdefault(path, []).extend(value if isinstance(value, list) else [value])

    def expected(self, path: str) -> np.ndarray:
        return np.asarray(self.values.get(path, []), dtype=np.float64)


def _t(name: str) -> type:
    return TYPESTORE.types[name]  # type: ignore[no-any-return]


def _header(sec: int, nanosec: int, frame: str) -> object:
    return _t("std_msgs/msg/Header")(
        stamp=_t("builtin_interfaces/msg/Time")(sec=sec, nanosec=nanosec), frame_id=frame
    )


def _stamp_values(prefix: str, sec: int, nanosec: int) -> dict[str, list[float] | float]:
    return {f"{prefix}stamp.sec": sec, f"{prefix}stamp.nanosec": nanosec}


def imu_data(rng: np.random.Generator, n: int, t0: int = T0, nan_every: int = 7) -> TopicData:
    """Imu messages with varying frame_id lengths and NaN in two fields."""
    data = TopicData("sensor_msgs/msg/Imu")
    vec = _t("geometry_msgs/msg/Vector3")
    quat = _t("geometry_msgs/msg/Quaternion")
    for i in range(n):
        sec, nanosec = 1_700_000_000 + i // 100, (i % 100) * 10_000_000
        o = rng.normal(size=4)
        w = rng.normal([0.0, 0.0, 0.0], 0.01)
        a = rng.normal([0.0, 0.0, 9.81], 0.05) + 1e4  # a large mean: catches naive variance
        if i % nan_every == 0:
            a[0] = np.nan
        cov = [rng.normal(size=9) for _ in range(3)]
        if i % (2 * nan_every) == 1:
            cov[0][4] = np.nan
        msg = _t("sensor_msgs/msg/Imu")(
            header=_header(sec, nanosec, FRAMES[i % len(FRAMES)]),
            orientation=quat(*o),
            orientation_covariance=cov[0],
            angular_velocity=vec(*w),
            angular_velocity_covariance=cov[1],
            linear_acceleration=vec(*a),
            linear_acceleration_covariance=cov[2],
        )
        values: dict[str, list[float] | float] = _stamp_values("header.", sec, nanosec)
        values.update({f"orientation.{k}": float(v) for k, v in zip("xyzw", o, strict=True)})
        for name, vector in (("angular_velocity", w), ("linear_acceleration", a)):
            values.update({f"{name}.{k}": float(v) for k, v in zip("xyz", vector, strict=True)})
        for name, matrix in zip(
            ("orientation", "angular_velocity", "linear_acceleration"), cov, strict=True
        ):
            values.update({f"{name}_covariance[{j}]": float(v) for j, v in enumerate(matrix)})
        data.add(t0 + i * 10_000_000, msg, values)
    return data


def scan_data(rng: np.random.Generator, n: int, t0: int = T0) -> TopicData:
    """LaserScan messages with ranges of varying length (some empty) holding NaN."""
    data = TopicData("sensor_msgs/msg/LaserScan")
    for i in range(n):
        ranges = rng.uniform(0.1, 30.0, size=int(rng.integers(0, 20))).astype(np.float32)
        ranges[::5] = np.nan
        intensities = rng.uniform(0, 1, size=int(rng.integers(0, 4))).astype(np.float32)
        angle_min = float(np.float32(rng.normal()))
        msg = _t("sensor_msgs/msg/LaserScan")(
            header=_header(i, 0, FRAMES[(i * 3) % len(FRAMES)]),
            angle_min=angle_min,
            angle_max=1.5,
            angle_increment=0.01,
            time_increment=0.0,
            scan_time=0.1,
            range_min=0.1,
            range_max=30.0,
            ranges=ranges,
            intensities=intensities,
        )
        values: dict[str, list[float] | float] = _stamp_values("header.", i, 0)
        values.update(
            {
                "angle_min": angle_min,
                "angle_max": 1.5,
                "angle_increment": float(np.float32(0.01)),
                "time_increment": 0.0,
                "scan_time": float(np.float32(0.1)),
                "range_min": float(np.float32(0.1)),
                "range_max": 30.0,
                "ranges[]": [float(v) for v in ranges],
                "intensities[]": [float(v) for v in intensities],
            }
        )
        data.add(t0 + 5_000_000 + i * 100_000_000, msg, values)
    return data


def diagnostics_data(rng: np.random.Generator, n: int, t0: int = T0) -> TopicData:
    """DiagnosticArray messages (sequences of messages: the general decoding path)."""
    data = TopicData("diagnostic_msgs/msg/DiagnosticArray")
    status = _t("diagnostic_msgs/msg/DiagnosticStatus")
    for i in range(n):
        levels = [int(v) for v in rng.integers(0, 4, size=int(rng.integers(0, 4)))]
        msg = _t("diagnostic_msgs/msg/DiagnosticArray")(
            header=_header(i, 7, "diag"),
            status=[
                status(level=v, name=f"s{v}", message="m", hardware_id="", values=[])
                for v in levels
            ],
        )
        values: dict[str, list[float] | float] = _stamp_values("header.", i, 7)
        values["status[].level"] = [float(v) for v in levels]
        data.add(t0 + 7_000_000 + i * 250_000_000, msg, values)
    return data


def flag_data(n: int, t0: int = T0) -> TopicData:
    """std_msgs/Bool: booleans count as 0/1."""
    data = TopicData("std_msgs/msg/Bool")
    for i in range(n):
        value = i % 3 == 0
        data.add(
            t0 + 3_000_000 + i * 500_000_000,
            _t("std_msgs/msg/Bool")(data=value),
            {"data": float(value)},
        )
    return data


@dataclass
class RawTopic:
    """Payloads written as given (crafted, hostile), with a definition of one's own or none
    (then the type's from rosbags' Jazzy types)."""

    type: str
    messages: list[tuple[int, bytes]] = field(default_factory=list)
    definition: str | None = None


def write_bag(
    path: Path,
    topics: dict[str, TopicData],
    *,
    compressed: bool = True,
    raw: dict[str, RawTopic] | None = None,
) -> Path:
    """Write ``topics`` into a rosbag2 (version 9, MCAP) bag at ``path`` with rosbags.

    ``raw`` adds payloads as they are: on a topic of ``topics`` (same type) among its
    messages, or on a topic of their own.
    """
    raw = raw or {}
    writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    if compressed:
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with writer:
        connections = {
            topic: writer.add_connection(topic, data.type, typestore=TYPESTORE)
            for topic, data in topics.items()
        }
        for topic, extra in raw.items():
            if topic in connections:
                continue
            if extra.definition is None:
                connections[topic] = writer.add_connection(topic, extra.type, typestore=TYPESTORE)
            else:
                connections[topic] = writer.add_connection(
                    topic, extra.type, msgdef=extra.definition, rihs01="RIHS01_" + "0" * 64
                )
        ordered = sorted(
            [
                (log_time, topic, bytes(TYPESTORE.serialize_cdr(msg, data.type)))
                for topic, data in topics.items()
                for log_time, msg in data.messages
            ]
            + [(t, topic, payload) for topic, extra in raw.items() for t, payload in extra.messages]
        )
        for log_time, topic, payload in ordered:
            writer.write(connections[topic], log_time, payload)
    return path


def check_topic(stats: Any, data: TopicData, mask: np.ndarray | None = None) -> None:
    """Every reported field against numpy on the values the generator wrote."""
    assert stats.type == data.type
    assert {f.field for f in stats.fields} == set(data.values)
    for f in stats.fields:
        values = data.expected(f.field)
        if mask is not None:
            values = values[mask]
        finite = values[~np.isnan(values)]
        assert f.count == len(finite), f.field
        assert f.nan_count == int(np.isnan(values).sum()), f.field
        if not len(finite):
            assert f.min is None and f.mean is None and f.std is None
            continue
        assert f.min == finite.min() and f.max == finite.max(), f.field
        assert f.mean == pytest.approx(finite.mean(), rel=RTOL, abs=1e-12), f.field
        if len(finite) > 1:
            assert f.std == pytest.approx(finite.std(ddof=1), rel=RTOL, abs=1e-12), f.field
        else:
            assert f.std is None
