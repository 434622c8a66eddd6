"""Snapshot mode: writing a 100 MiB snapshot against ``cp``, the trigger's latency, and the
recording going on while a 100 MiB snapshot is written.

1. A 100 MiB snapshot (100 images of 1 MiB, incompressible) written by the snapshot writer
   thread (zstd chunks, as ``bagkit record``) against ``cp`` of a 100 MiB file, interleaved,
   best of 3 each. Target: at least half of ``cp``'s speed.
2. From the trigger message's receipt (its log time: the middleware's receive stamp) to the
   snapshot's first byte on disk (its file created with the MCAP header), over real DDS in one
   process: a 200 Hz Imu stream and 40 ERROR alerts 0.25 s apart, each opening a snapshot
   (``--post 0``). Reported as p50/p99; no target.
3. A snapshot-mode recording over real DDS in one process (1 MiB images at 30 Hz and a 200 Hz
   Imu stream, reliable, a 102 MiB buffer) is triggered (``Recorder.snapshot()``, ``--post 0``)
   once the buffer is full; the recording goes on while the snapshot thread writes the ~100 MiB
   snapshot (timed from the trigger to its ``metadata.yaml``), then for 2 s more.
   Target: 0 messages lost (the report's gaps, overflows and failed writes), the snapshot
   written whole.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import threading
import time
from pathlib import Path

from bagkit.bag import BagWriter, TopicInfo
from bagkit.recording import snapshot_writer
from bagkit.recording.report import SnapshotRecord
from bagkit.recording.snapshot_buffer import MessageSlice
from bagkit.recording.snapshot_writer import (
    SnapshotEnd,
    SnapshotMessages,
    SnapshotStart,
    SnapshotWriter,
)

MIB = 1 << 20
IMAGE_TYPE = "sensor_msgs/msg/Image"
ROUNDS = 3
TRIGGERS = 40
CAMERA_HZ = 30
IMU_HZ = 200
# The snapshot buffer's bound: 100 images of 1 MiB and the Imu messages beside them.
SNAPSHOT_BUFFER = 102 * MIB


def _write_snapshot(directory: Path, images: list[bytes], compression: str) -> float:
    """Seconds for the snapshot writer to write ``images`` as one snapshot and finish it."""
    errors: list[str] = []
    writer = SnapshotWriter(compression, {}, errors.append)
    record = SnapshotRecord(directory / "snapshot", "bench", 0, 0, len(images))
    start = time.perf_counter()
    writer.put(SnapshotStart(record, [(TopicInfo("/camera", IMAGE_TYPE), "")], []))
    for index in range(0, len(images), 8):
        part = images[index : index + 8]
        times = list(range(index, index + len(part)))
        writer.put(SnapshotMessages(record, MessageSlice("/camera", part, times, times, times)))
    writer.put(SnapshotEnd(record))
    writer.close()
    elapsed = time.perf_counter() - start
    assert not errors and record.messages["/camera"] == len(images), errors
    return elapsed


def _cp(source: Path, target: Path) -> float:
    start = time.perf_counter()
    subprocess.run(["cp", str(source), str(target)], check=True)
    return time.perf_counter() - start


def bench_write_speed() -> bool:
    """Snapshot writer vs cp of the same size, interleaved, best of ROUNDS."""
    images = [os.urandom(MIB) for _ in range(100)]
    seconds: dict[str, list[float]] = {"cp": [], "zstd": [], "none": []}
    with tempfile.TemporaryDirectory() as scratch:
        base = Path(scratch)
        source = base / "source.bin"
        source.write_bytes(b"".join(images))
        for round_ in range(ROUNDS):
            seconds["cp"].append(_cp(source, base / f"copy{round_}.bin"))
            (base / f"copy{round_}.bin").unlink()
            for compression in ("zstd", "none"):
                target = base / f"{compression}{round_}"
                seconds[compression].append(_write_snapshot(target, images, compression))
                shutil.rmtree(target)
    rates = {name: 100 / min(values) for name, values in seconds.items()}
    for name in ("zstd", "none"):
        print(
            f"100 MiB snapshot, {name} chunks: {rates[name]:.0f} MiB/s, cp {rates['cp']:.0f} "
            f"MiB/s, ratio {rates[name] / rates['cp']:.2f} (target >= 0.5 for zstd, the default)"
        )
    print(f"all rounds, seconds: { ({k: [round(x, 3) for x in v] for k, v in seconds.items()}) }")
    return rates["zstd"] / rates["cp"] >= 0.5


def bench_trigger_latency() -> bool:
    """p50/p99 from the trigger message's receipt to its snapshot's first byte on disk."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from rclpy.context import Context
    from rclpy.node import Node
    from sensor_msgs.msg import Imu

    from bagkit.recording.options import RecordOptions, SnapshotOptions, SnapshotTrigger
    from bagkit.ros.record.recorder import Recorder

    opened: dict[Path, int] = {}
    original_open = BagWriter.open

    def timed_open(bag: BagWriter) -> BagWriter:
        result = original_open(bag)
        opened.setdefault(bag.path, time.time_ns())  # the header is on disk now
        return result

    snapshot_writer.BagWriter.open = timed_open  # type: ignore[method-assign,assignment]
    context = Context()
    rclpy.init(context=context)
    node = Node("bench_snapshot_publisher", context=context)
    imu = node.create_publisher(Imu, "/bench/imu", 1000)
    alerts = node.create_publisher(DiagnosticArray, "/bench/alerts", 10)
    stop = threading.Event()

    def stream() -> None:
        while not stop.is_set():
            imu.publish(Imu())
            time.sleep(0.005)

    streamer = threading.Thread(target=stream, daemon=True)
    try:
        with tempfile.TemporaryDirectory() as scratch:
            options = RecordOptions(
                Path(scratch) / "latency",
                regex="^/bench/",
                snapshot=SnapshotOptions(
                    max_duration_ns=1_000_000_000,
                    triggers=(SnapshotTrigger.parse("/bench/alerts: status[*].level >= 2"),),
                ),
            )
            with Recorder(options) as recorder:
                deadline = time.monotonic() + 30
                while imu.get_subscription_count() < 1 or alerts.get_subscription_count() < 1:
                    assert time.monotonic() < deadline, "the recorder did not subscribe"
                    time.sleep(0.05)
                streamer.start()
                time.sleep(1.0)
                error = DiagnosticArray(status=[DiagnosticStatus(level=DiagnosticStatus.ERROR)])
                for _ in range(TRIGGERS):
                    alerts.publish(error)
                    time.sleep(0.25)
                time.sleep(0.5)
            stop.set()
            snapshots = recorder.report.snapshots or []
            latencies = sorted((opened[s.path] - s.trigger_ns) / 1e6 for s in snapshots)
    finally:
        stop.set()
        snapshot_writer.BagWriter.open = original_open  # type: ignore[method-assign]
        node.destroy_node()
        context.try_shutdown()
    if len(latencies) < TRIGGERS:
        print(f"trigger latency: only {len(latencies)} of {TRIGGERS} snapshots")
        return False
    p50 = latencies[len(latencies) // 2]
    p99 = latencies[min(len(latencies) - 1, round(0.99 * (len(latencies) - 1)))]
    print(
        f"trigger -> snapshot's first byte: p50 {p50:.1f} ms, p99 {p99:.1f} ms, max "
        f"{latencies[-1]:.1f} ms ({len(latencies)} snapshots, 200 Hz Imu beside)"
    )
    return True


def bench_recording_meanwhile() -> bool:
    """A ~100 MiB snapshot written while the recording goes on: messages lost (target 0)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image, Imu

    from bagkit.recording.options import RecordOptions, SnapshotOptions
    from bagkit.ros.record.recorder import Recorder
    from bagkit.ros.serialization import serialize

    image = serialize(
        Image(height=1024, width=1024, encoding="mono8", step=1024, data=os.urandom(MIB))
    )
    imu_message = serialize(Imu())
    context = Context()
    rclpy.init(context=context)
    node = Node("bench_snapshot_meanwhile", context=context)
    reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    camera = node.create_publisher(Image, "/bench/camera", reliable)
    imu = node.create_publisher(Imu, "/bench/imu", reliable)
    stop = threading.Event()
    published = {"/bench/camera": 0, "/bench/imu": 0}

    def stream() -> None:
        # Steady rates whatever a publish costs: each message at its due time (or at once when
        # late), an image every 1/CAMERA_HZ s and an Imu every 1/IMU_HZ s.
        start = time.monotonic()
        while not stop.is_set():
            now = time.monotonic() - start
            if published["/bench/camera"] <= now * CAMERA_HZ:
                camera.publish(image)
                published["/bench/camera"] += 1
            if published["/bench/imu"] <= now * IMU_HZ:
                imu.publish(imu_message)
                published["/bench/imu"] += 1
            due = min(published["/bench/camera"] / CAMERA_HZ, published["/bench/imu"] / IMU_HZ)
            time.sleep(max(0.0, due - (time.monotonic() - start)))

    streamer = threading.Thread(target=stream, daemon=True)
    try:
        with tempfile.TemporaryDirectory() as scratch:
            options = RecordOptions(
                Path(scratch) / "meanwhile",
                regex="^/bench/(camera|imu)$",
                snapshot=SnapshotOptions(max_bytes=SNAPSHOT_BUFFER),
            )
            with Recorder(options) as recorder:
                deadline = time.monotonic() + 30
                while camera.get_subscription_count() < 1 or imu.get_subscription_count() < 1:
                    assert time.monotonic() < deadline, "the recorder did not subscribe"
                    time.sleep(0.05)
                streamer.start()
                # Fill the buffer to its bound (and a little past it: the oldest are evicted).
                time.sleep(1.2 * SNAPSHOT_BUFFER / MIB / CAMERA_HZ)
                taken_before = recorder.progress().messages
                triggered = time.monotonic()
                snapshot = recorder.snapshot("bench")
                finished = snapshot.path / "metadata.yaml"
                while not finished.exists() and time.monotonic() < triggered + 30:
                    time.sleep(0.001)
                written_s = time.monotonic() - triggered
                whole = finished.exists()
                taken_meanwhile = recorder.progress().messages - taken_before
                time.sleep(2.0)  # and on after it
                stop.set()
                streamer.join()
                time.sleep(0.5)  # the last messages reach the recorder
            snapshot_mib = sum(f.stat().st_size for f in snapshot.path.iterdir()) / MIB
            report = recorder.report
    finally:
        stop.set()
        node.destroy_node()
        context.try_shutdown()
    topics = {t.topic: t for t in report.topics}
    losses = ", ".join(
        f"{name} {t.lost} (gaps {t.gaps}, overflow {t.overflow}, write failed {t.write_failed})"
        for name, t in sorted(topics.items())
    )
    taken = {name: t.messages for name, t in sorted(topics.items())}
    print(
        f"recording while a {snapshot_mib:.0f} MiB snapshot is written (trigger -> its "
        f"metadata.yaml {written_s * 1000:.0f} ms, {taken_meanwhile} messages taken meanwhile): "
        f"lost {report.lost} (target 0); per topic: {losses}"
    )
    print(
        f"  published {published}, taken {taken}, snapshot "
        f"{snapshot.messages} messages, error {snapshot.error or report.error}"
    )
    complete = whole and snapshot.error is None and report.error is None
    return report.lost == 0 and complete and snapshot_mib >= 90


def main() -> bool:
    """The three benchmarks; False if a target was missed."""
    speed = bench_write_speed()
    latency = bench_trigger_latency()
    meanwhile = bench_recording_meanwhile()
    return speed and latency and meanwhile
