"""Helpers of the surgery tests: sample bags written by bagkit, read back by independent oracles
(rosbags' AnyReader, the ``mcap`` package's reader)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from bagkit_runs import bagkit_in_process
from mcap.reader import make_reader
from ros2_messages import IMU, STRING, TEMPERATURE, TYPESTORE, imu_cdr, qos_yaml, string_cdr
from rosbags.highlevel import AnyReader

from bagkit.bag import BagWriter, TopicInfo

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
START = 1_763_850_000_000_000_000
QOS = qos_yaml(depth=7, reliability="best_effort", durability="transient_local")

Message = tuple[str, int, bytes]  # topic, log time, payload


def temperature_cdr(i: int) -> bytes:
    t = TYPESTORE.types
    header = t["std_msgs/msg/Header"](
        stamp=t["builtin_interfaces/msg/Time"](sec=i, nanosec=0), frame_id="thermo"
    )
    msg = t[TEMPERATURE](header=header, temperature=20.0 + 0.1 * i, variance=0.0)
    return bytes(TYPESTORE.serialize_cdr(msg, TEMPERATURE))


def write_mixed_bag(
    path: Path,
    n: int = 2000,
    *,
    offset_ns: int = 0,
    step_ns: int = 10_000_000,
    compression: str = "zstd",
    chunk_size: int = 16 << 10,
) -> Path:
    """A bag of three topics at different rates (/imu/data every step, /text every 7th,
    /temperature every 50th), small chunks so that there are many."""
    with BagWriter(path, compression=compression, chunk_size=chunk_size) as bag:
        bag.add_topic(TopicInfo("/imu/data", IMU, offered_qos_profiles=QOS))
        bag.add_topic(TopicInfo("/text", STRING, offered_qos_profiles=QOS))
        bag.add_topic(TopicInfo("/temperature", TEMPERATURE, offered_qos_profiles=QOS))
        for i in range(n):
            t = START + offset_ns + i * step_ns
            bag.write("/imu/data", imu_cdr(i), log_time=t, publish_time=t - 5, sequence=i)
            if i % 7 == 0:
                bag.write("/text", string_cdr(f"text {i}"), log_time=t + 1, sequence=i)
            if i % 50 == 0:
                bag.write("/temperature", temperature_cdr(i), log_time=t + 2, sequence=i)
    return path


def rosbags_messages(path: Path) -> list[Message]:
    """Every message of a bag as rosbags reads it, in its order."""
    with AnyReader([path]) as reader:
        return [(c.topic, t, bytes(raw)) for c, t, raw in reader.messages()]


def mcap_messages(files: list[Path]) -> list[Message]:
    """Every message of MCAP files as the ``mcap`` package reads them (summary used, CRCs
    validated), in log-time order (ties: file order)."""
    found: list[tuple[int, int, int, str, bytes]] = []
    for rank, file in enumerate(files):
        with open(file, "rb") as f:
            reader = make_reader(f, validate_crcs=True)
            assert reader.get_summary() is not None, f"{file} has no summary"
            for i, (_, channel, message) in enumerate(reader.iter_messages(log_time_order=True)):
                found.append((message.log_time, rank, i, channel.topic, bytes(message.data)))
    found.sort()
    return [(topic, t, data) for t, _, _, topic, data in found]


def chunk_records(file: Path) -> list[bytes]:
    """The Chunk records of an MCAP file as stored (found by walking its data section)."""
    data = file.read_bytes()
    pos, records = 8, []
    while pos + 9 <= len(data):
        opcode = data[pos]
        length = int.from_bytes(data[pos + 1 : pos + 9], "little")
        if opcode in (0x0F, 0x02):  # Data End, Footer
            break
        if opcode == 0x06:
            records.append(data[pos : pos + 9 + length])
        pos += 9 + length
    return records


def run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [BAGKIT, *args], capture_output=True, text=True, timeout=120, check=False, cwd=cwd
    )


def run_here(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """What ``run`` answers, from ``bagkit`` in this process (tests/bagkit_runs.py): each test
    module keeps a real process for one of its runs."""
    return bagkit_in_process(list(args), cwd)


def key(message: Message) -> tuple[int, str, bytes]:
    return message[1], message[0], message[2]
