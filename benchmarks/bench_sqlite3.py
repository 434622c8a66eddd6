"""``stats summary`` of 1,000,000 ``sensor_msgs/msg/Imu`` messages stored as a rosbag2 sqlite3
bag with message-compressed zstd payloads (``--compression-mode message``) against the same
messages as bagkit's MCAP bag (bench_stats' bag), in the same run: target >= 0.5 (the
decompression and SQLite's row reading are the only extra work).

The db3 bag is written once by rosbags' rosbag2 writer (zstd per message, as rosbag2 does)
from the MCAP bag and cached under benchmarks/results/ (gitignored).

Run: ``.venv/bin/python -m benchmarks sqlite3``
"""

from __future__ import annotations

from pathlib import Path

from benchmarks.bench_stats import LARGE, RESULTS, imu_bag
from benchmarks.timing import best_of_with_cpu

RATIO_FLOOR = 0.5
RUNS = 3


def message_compressed_db3(source: Path) -> Path:
    """The messages of ``source`` as a rosbags-written sqlite3 bag, zstd per message."""
    path = RESULTS / f"sqlite3_zstd_message_{LARGE}"
    if (path / "metadata.yaml").is_file():
        return path
    import shutil

    from rosbags.rosbag2 import Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
    from rosbags.typesys import Stores, get_typestore

    from bagkit.bag import BagReader

    if path.exists():  # an interrupted generation: metadata.yaml is written last
        shutil.rmtree(path)
    store = get_typestore(Stores.ROS2_JAZZY)
    writer = Writer(path, version=9)
    writer.set_compression(CompressionMode.MESSAGE, CompressionFormat.ZSTD)
    with writer, BagReader(source) as bag:
        connections = {
            name: writer.add_connection(name, topic.type, typestore=store)
            for name, topic in bag.topics.items()
        }
        for message in bag.messages():
            writer.write(connections[message.topic], message.log_time, message.data)
    return path


def _summary_seconds(bag: Path) -> tuple[float, float]:
    from bagkit.stats import summarize

    def summary() -> None:
        assert summarize([bag]).topics[0].count == LARGE

    return best_of_with_cpu(RUNS, summary)


def main() -> bool:
    """Measure both bags in the same run; True when the ratio meets its floor."""
    mcap = imu_bag(LARGE)
    db3 = message_compressed_db3(mcap)
    mcap_s, mcap_cpu = _summary_seconds(mcap)
    db3_s, db3_cpu = _summary_seconds(db3)
    ratio = mcap_s / db3_s
    print(f"stats summary, MCAP (zstd chunks)         {mcap_s:6.2f} s (CPU {mcap_cpu:.2f} s)")
    print(f"stats summary, sqlite3, zstd per message  {db3_s:6.2f} s (CPU {db3_cpu:.2f} s)")
    print(
        f"speed ratio db3/MCAP {ratio:.2f} (target >= {RATIO_FLOOR}); "
        f"by CPU {mcap_cpu / db3_cpu:.2f}"
    )
    return ratio >= RATIO_FLOOR
