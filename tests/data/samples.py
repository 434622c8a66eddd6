"""Bags of random messages of many types, written with bagkit's writer from rosbags' encoder."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from bagkit.bag import BagWriter, TopicInfo

JAZZY = get_typestore(Stores.ROS2_JAZZY)
# Fixed layouts (bulk path), sequences of structs and strings (general path), bools, octets.
SAMPLE_TYPES = {
    "/imu": "sensor_msgs/msg/Imu",
    "/scan": "sensor_msgs/msg/LaserScan",
    "/joints": "sensor_msgs/msg/JointState",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
    "/odom": "nav_msgs/msg/Odometry",
    "/flag": "std_msgs/msg/Bool",
    "/text": "std_msgs/msg/String",
    "/fix": "sensor_msgs/msg/NavSatFix",
    "/roi": "sensor_msgs/msg/RegionOfInterest",
    "/image": "sensor_msgs/msg/Image",
}
FRAMES = ("base_link", "imu", "", "odom_ü")


def _primitives(rng: np.random.Generator, base: str, n: int) -> np.ndarray:
    if base == "bool":
        return rng.integers(0, 2, n).astype(bool)
    dtype = np.dtype({"byte": "u1", "char": "u1"}.get(base, base))
    if dtype.kind == "f":
        values = rng.normal(0, 1e3, n).astype(dtype)
        values[rng.random(n) < 0.1] = np.nan
        values[rng.random(n) < 0.05] = np.inf
        return values
    info = np.iinfo(dtype)
    return rng.integers(info.min, info.max, n, dtype=dtype, endpoint=True)


def _value(ts: Typestore, desc: Any, rng: np.random.Generator, name: str) -> Any:
    kind, rest = desc
    if kind == Nodetype.BASE:
        if rest[0] == "string":
            if name == "frame_id":  # a few values: bulk groups by string length
                return FRAMES[int(rng.integers(0, len(FRAMES)))]
            return "".join(chr(c) for c in rng.integers(97, 123, int(rng.integers(0, 9))))
        value = _primitives(rng, rest[0], 1)[0]
        if rest[0] == "byte":
            return int(value) - 256 if value > 127 else int(value)  # rosbags packs byte as int8
        return bool(value) if rest[0] == "bool" else value.item()
    if kind == Nodetype.NAME:
        return random_message(ts, rest, rng)
    sub, bound = rest
    # Sequences are short, but for a blob's ``data`` (long enough to be cut by echo).
    longest = 300 if name == "data" else 5
    n = bound if kind == Nodetype.ARRAY else int(rng.integers(0, (bound or longest) + 1))
    if sub[0] == Nodetype.BASE and sub[1][0] != "string":
        return _primitives(rng, sub[1][0], n)
    return [_value(ts, sub, rng, name) for _ in range(n)]


def random_message(ts: Typestore, typename: str, rng: np.random.Generator) -> object:
    """A message with random values (NaN and inf among floats), strings, sequence lengths."""
    fields = {name: _value(ts, desc, rng, name) for name, desc in ts.fielddefs[typename][1]}
    return ts.types[typename](**fields)


def write_sample_bag(
    path: Path, count: int = 300, seed: int = 1, *, chunk_size: int = 16 * 1024
) -> Path:
    """A bag of ``count`` random messages on each topic of SAMPLE_TYPES, several chunks."""
    rng = np.random.default_rng(seed)
    with BagWriter(path, chunk_size=chunk_size) as bag:
        for topic, typename in SAMPLE_TYPES.items():
            bag.add_topic(TopicInfo(topic, typename))
        t = 1_700_000_000_000_000_000
        for i in range(count):
            for k, (topic, typename) in enumerate(SAMPLE_TYPES.items()):
                msg = random_message(JAZZY, typename, rng)
                data = bytes(JAZZY.serialize_cdr(msg, typename))
                t += 1_000_000 + k
                bag.write(topic, data, log_time=t, publish_time=t - 5000 - i)
    return path
