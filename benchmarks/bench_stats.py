"""``stats summary`` on 1,000,000 ``sensor_msgs/msg/Imu`` messages against rosbags, and its
peak memory on bags 10x apart in size.

Peers measured in the same run, on the same bag:
- rosbags + rosbags-dataframe: ``get_dataframe`` on every numeric field (the covariance arrays
  expanded into columns), then pandas min/max/mean/std: target at least 20x slower than us;
- rosbags iterating the raw messages without decoding them: target at least 2x slower.
Peak RSS of a summary of the 1M bag vs the 100k bag (each in a fresh subprocess): at most 1.5x.
The general path (``bulk=False``: leaf values read straight from the CDR bytes, what types with
sequences of messages and the messages bulk decoding leaves over use) on the 100k bag against
rosbags iterating and deserializing the same messages: target no slower (>= 1x).

The bags are generated once (one serialized template, fields varied with numpy, written with
bagkit's writer, zstd chunks) and cached under benchmarks/results/ (gitignored).

Run: ``.venv/bin/python -m benchmarks stats``
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

IMU = "sensor_msgs/msg/Imu"
TOPIC = "/imu/data"
LARGE, SMALL = 1_000_000, 100_000
RESULTS = Path(__file__).resolve().parent / "results"
T0 = 1_700_000_000_000_000_000
SPEEDUP_VS_DATAFRAME = 20.0
SPEEDUP_VS_RAW_ITERATION = 2.0
GENERAL_VS_DESERIALIZE = 1.0
RSS_RATIO_CEILING = 1.5
SCALARS = [
    "header.stamp.sec",
    "header.stamp.nanosec",
    *(f"orientation.{k}" for k in "xyzw"),
    *(f"angular_velocity.{k}" for k in "xyz"),
    *(f"linear_acceleration.{k}" for k in "xyz"),
]
ARRAYS = ["orientation_covariance", "angular_velocity_covariance", "linear_acceleration_covariance"]


def imu_bag(n: int) -> Path:
    """A cached bag of ``n`` Imu messages at 100 Hz with random values in every numeric field."""
    path = RESULTS / f"stats_imu_{n}"
    if (path / "metadata.yaml").is_file():
        return path
    from rosbags.typesys import Stores, get_typestore

    from bagkit.bag import BagWriter, TopicInfo
    from bagkit.decode.layout import CdrLayout, ResolvedLayout

    store = get_typestore(Stores.ROS2_JAZZY)
    t = store.types
    template = t[IMU](
        header=t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="imu_link"
        ),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
        linear_acceleration_covariance=np.zeros(9),
    )
    payload = np.frombuffer(bytes(store.serialize_cdr(template, IMU)), np.uint8)
    layout = CdrLayout.of(store, IMU)
    assert layout is not None
    resolved = layout.resolve((len("imu_link") + 1,))
    assert isinstance(resolved, ResolvedLayout) and resolved.dtype.itemsize == len(payload)
    rng = np.random.default_rng(5)
    if path.exists():  # an interrupted generation: metadata.yaml is written last
        shutil.rmtree(path)
    with BagWriter(path) as bag:
        bag.add_topic(TopicInfo(TOPIC, IMU))
        for start in range(0, n, 100_000):
            stop = min(n, start + 100_000)
            # Per block, so that a bag of tens of millions of messages is made in little memory.
            log_times = T0 + np.arange(start, stop, dtype=np.int64) * 10_000_000
            raw = np.tile(payload, (stop - start, 1))
            records = raw.view(resolved.dtype).ravel()
            for name in resolved.dtype.names or ():
                if records[name].dtype.kind == "S":  # header.frame_id stays "imu_link"
                    continue
                shape = records[name].shape
                records[name] = rng.normal(0.0, 1.0, shape)
            records["0"] = log_times // 10**9
            records["1"] = log_times % 10**9
            for row, log_time in zip(raw, log_times.tolist(), strict=True):
                bag.write(TOPIC, row.tobytes(), log_time=log_time)
    return path


def _seconds(func: object, runs: int = 1) -> float:
    best = float("inf")
    for _ in range(runs):
        start = time.perf_counter()
        func()  # type: ignore[operator]
        best = min(best, time.perf_counter() - start)
    return best


def _bagkit(bag: Path) -> None:
    from bagkit.stats import summarize

    summary = summarize([bag])
    assert summary.topics[0].count == LARGE


def rosbags_dataframe(bag: Path) -> None:
    """The peer: rosbags-dataframe's frame of every numeric field, then pandas' moments."""
    import pandas as pd
    from rosbags.dataframe import get_dataframe
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        frame = get_dataframe(reader, TOPIC, [*SCALARS, *ARRAYS])
    columns = [frame[SCALARS].astype("float64")]
    for name in ARRAYS:
        matrix = np.stack(frame[name].to_numpy())
        columns.append(pd.DataFrame(matrix, columns=[f"{name}[{i}]" for i in range(9)]))
    numeric = pd.concat([c.reset_index(drop=True) for c in columns], axis=1)
    stats = numeric.agg(["count", "min", "max", "mean", "std"])
    assert stats.shape[1] == 39 and stats.loc["count"].iloc[0] == LARGE


def _bagkit_general(bag: Path) -> None:
    from bagkit.stats import summarize

    summary = summarize([bag], bulk=False)
    assert summary.topics[0].count == SMALL


def _rosbags_deserialize(bag: Path) -> None:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    count = 0
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        for connection, _, raw in reader.messages():
            reader.deserialize(raw, connection.msgtype)
            count += 1
    assert count == SMALL


def _rosbags_raw(bag: Path) -> None:
    from rosbags.highlevel import AnyReader

    count = 0
    with AnyReader([bag]) as reader:
        for _ in reader.messages():
            count += 1
    assert count == LARGE


# VmHWM (peak resident set of this process image) restarts at exec, unlike ru_maxrss, which
# keeps the size of the parent that forked the probe.
_RSS_PROBE = """
import json, re, sys
from bagkit.stats import summarize

def peak_kib():
    with open("/proc/self/status") as f:
        return int(re.search(r"VmHWM:\\s+(\\d+)", f.read()).group(1))

baseline = peak_kib()
summary = summarize([sys.argv[1]])
count = summary.topics[0].count
print(json.dumps({"baseline_kib": baseline, "peak_kib": peak_kib(), "count": count}))
"""


def _peak_rss(bag: Path) -> dict[str, int]:
    out = subprocess.run(
        [sys.executable, "-c", _RSS_PROBE, str(bag)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return json.loads(out)


def main() -> bool:
    """Run the measurements, print the ratios; True when every target is met."""
    RESULTS.mkdir(exist_ok=True)
    start = time.perf_counter()
    large, small = imu_bag(LARGE), imu_bag(SMALL)
    print(f"bags ready in {time.perf_counter() - start:.1f} s ({large.name}, {small.name})")

    ours = _seconds(lambda: _bagkit(large), runs=5)  # short: best of 5 against load spikes
    raw = _seconds(lambda: _rosbags_raw(large))
    frame = _seconds(lambda: rosbags_dataframe(large))
    print(f"bagkit stats summary      {ours:7.2f} s  {LARGE / ours / 1e6:6.2f} M msg/s")
    print(f"rosbags raw iteration     {raw:7.2f} s  {LARGE / raw / 1e6:6.2f} M msg/s")
    print(f"rosbags + dataframe/pandas {frame:6.2f} s  {LARGE / frame / 1e6:6.2f} M msg/s")
    vs_frame, vs_raw = frame / ours, raw / ours
    print(f"speedup vs rosbags+dataframe: {vs_frame:6.1f}x (target >= {SPEEDUP_VS_DATAFRAME:g}x)")
    print(f"speedup vs rosbags raw:       {vs_raw:6.1f}x (target >= {SPEEDUP_VS_RAW_ITERATION:g}x)")

    general = _seconds(lambda: _bagkit_general(small), runs=3)
    deserialize = _seconds(lambda: _rosbags_deserialize(small), runs=3)
    vs_deserialize = deserialize / general
    print(
        f"general path (bulk=False) {general:6.2f} s vs rosbags deserialize {deserialize:.2f} s "
        f"on {SMALL:,} msgs: {vs_deserialize:.2f}x (target >= {GENERAL_VS_DESERIALIZE:g}x)"
    )

    rss_small, rss_large = _peak_rss(small), _peak_rss(large)
    assert (rss_small["count"], rss_large["count"]) == (SMALL, LARGE)
    ratio = rss_large["peak_kib"] / rss_small["peak_kib"]
    print(
        f"peak RSS: {rss_small['peak_kib'] / 1024:.0f} MiB for {SMALL:,} msgs, "
        f"{rss_large['peak_kib'] / 1024:.0f} MiB for {LARGE:,} "
        f"(after imports: {rss_small['baseline_kib'] / 1024:.0f} MiB); "
        f"ratio {ratio:.2f} (ceiling {RSS_RATIO_CEILING:g})"
    )
    return (
        vs_frame >= SPEEDUP_VS_DATAFRAME
        and vs_raw >= SPEEDUP_VS_RAW_ITERATION
        and vs_deserialize >= GENERAL_VS_DESERIALIZE
        and ratio <= RSS_RATIO_CEILING
    )
